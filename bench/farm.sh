#!/usr/bin/env bash
# farm.sh - what the farm costs, printed not asserted.
#   1. samples/s of the local farm against the single-process renderer on the
#      same scene, runs interleaved (this machine is shared and noisy: compare
#      the medians of one run, never numbers from different days);
#   2. the coordinator's own CPU time and bytes per tile;
#   3. a load test: loadgen opens N simulated workers that answer instantly.
# usage: bench/farm.sh BIN_DIR [SCENE] [SPP] [ROUNDS]
set -euo pipefail
bin=$1
scene=${2:-scenes/cornell-box.json}
spp=${3:-16}
rounds=${4:-3}
cores=$(nproc)
out=$(mktemp -d /tmp/tessera-farm-bench.XXXXXX)
trap 'rm -rf "$out"' EXIT

rate() { sed -n 's/.*, \([0-9.]*\) Msamples\/s.*/\1/p'; }
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
best() { sort -g | tail -1; }

echo "== farm vs single process: $scene, 512x512, $spp spp, $cores cores, $rounds rounds interleaved"
declare -A runs=(
  [single_${cores}_threads]="--workers 0 --threads $cores"
  [farm_${cores}_workers]="--workers $cores"
  [farm_1_worker_1_thread]="--workers 1 --threads 1"
  [single_1_thread]="--workers 0 --threads 1"
)
order=(single_${cores}_threads farm_${cores}_workers farm_1_worker_1_thread single_1_thread)
for r in $(seq "$rounds"); do
  for k in "${order[@]}"; do
    # shellcheck disable=SC2086
    "$bin/tessera" render "$scene" ${runs[$k]} --spp "$spp" --no-progress -v -o "$out/$k.pfm" \
      > "$out/$k.$r.out" 2> "$out/$k.$r.err"
    echo "  round $r $k: $(rate < "$out/$k.$r.out") Msamples/s"
  done
done
declare -A med top
for k in "${order[@]}"; do
  med[$k]=$(cat "$out/$k".*.out | rate | median)
  top[$k]=$(cat "$out/$k".*.out | rate | best)
  echo "$k: median ${med[$k]}, best ${top[$k]} Msamples/s"
done
for stat in median best; do
  if [ $stat = median ]; then s=${med[single_${cores}_threads]}; f=${med[farm_${cores}_workers]}
    one=${med[farm_1_worker_1_thread]}; s1=${med[single_1_thread]}
  else s=${top[single_${cores}_threads]}; f=${top[farm_${cores}_workers]}
    one=${top[farm_1_worker_1_thread]}; s1=${top[single_1_thread]}; fi
  awk -v s="$s" -v f="$f" -v o="$one" -v s1="$s1" -v c="$cores" -v st=$stat 'BEGIN {
    printf "%s: farm %d workers / single process %d threads = %.1f%% (target >= 95%%)\n", st, c, c, 100 * f / s
    printf "%s: farm %d workers / 1 worker 1 thread = %.2fx (target >= 1.9x); ", st, c, f / o
    printf "for scale, single process %d threads / 1 thread = %.2fx\n", c, s / s1 }'
done
cmp -s "$out/single_${cores}_threads.pfm" "$out/farm_${cores}_workers.pfm" \
  && echo "images: farm and single process are byte-identical" \
  || echo "images: DIFFER (a bug)"
echo "coordinator (last farm run): $(grep '^farm:' "$out/farm_${cores}_workers.$rounds.err")"

for n in 100 500; do
  echo "== load test: $n simulated workers answering instantly, 2048x2048 at 1 spp in 16x16 tiles (16384 tiles)"
  rm -f "$out/coord.log"
  /usr/bin/time -f "coordinator peak RSS %M KiB (the 2048x2048 float image and its encoded copy are 96 MiB of it)" \
    "$bin/tessera" render "$scene" --listen 127.0.0.1:0 --width 2048 --height 2048 --spp 1 --tile-size 16 \
    --no-progress -v -o "$out/load.pfm" > "$out/coord.out" 2> "$out/coord.log" &
  coord=$!
  for _ in $(seq 100); do grep -q "listening on" "$out/coord.log" 2>/dev/null && break; sleep 0.05; done
  port=$(sed -n 's/.*listening on 127.0.0.1:\([0-9]*\).*/\1/p' "$out/coord.log")
  "$bin/loadgen" --connect "127.0.0.1:$port" --connections "$n"
  wait "$coord"
  grep '^farm:' "$out/coord.log"
  grep 'peak RSS' "$out/coord.log"
done
