#!/usr/bin/env bash
# trust.sh - what encrypted links and audited tiles cost (issue 17), printed
# not asserted: the local farm on one scene, five configurations run
# interleaved round by round (the machine is shared and noisy: compare the
# medians of one run only):
#   plain     --workers N, no token (frames in clear on loopback)
#   sealed    --workers N --token-file T (every frame sealed, conn_seal)
#   audit-X   --workers N --audit X (X of the tiles rendered twice)
# and, in the same rounds, the load test (bench/loadgen.c: LOAD_CONNECTIONS
# simulated workers answering instantly; a 2048x2048 frame at 1 spp in
# 16x16 tiles, 16384 tiles) against `tessera render --listen`, with links in
# clear (load-plain) and sealed (load-sealed): tiles/s, coordinator CPU
# seconds. The load average is printed with every round.
# usage: [TRUST_CONFIGS="plain sealed"] [LOAD_CONFIGS="load-plain load-sealed"] [LOAD_CONNECTIONS=100]
#        bench/trust.sh BIN_DIR [SCENE] [SPP] [ROUNDS] [TILE]
set -euo pipefail
bin=$1
scene=${2:-scenes/cornell-box.json}
spp=${3:-16}
rounds=${4:-5}
tile=${5:-32}
workers=$(nproc)
[ "$workers" -lt 3 ] && workers=3 # an audit mismatch needs a third worker
out=$(mktemp -d /tmp/tessera-trust-bench.XXXXXX)
trap 'rm -rf "$out"' EXIT
echo "bench token $$" > "$out/token"
declare -A runs=(
  [plain]="--audit 0"
  [sealed]="--audit 0 --token-file $out/token"
  [audit-0.02]="--audit 0.02"
  [audit-0.1]="--audit 0.1"
  [audit-1.0]="--audit 1.0"
)
read -r -a order <<< "${TRUST_CONFIGS:-plain sealed audit-0.02 audit-0.1 audit-1.0}"
read -r -a loads <<< "${LOAD_CONFIGS-load-plain load-sealed}"
conns=${LOAD_CONNECTIONS:-100}
loadavg() { cut -d' ' -f1 /proc/loadavg; }

# One load test: prints "TILES_PER_S CPU_S" (the coordinator's user+system).
load_once() {
  local k=$1 tok=() log="$out/$1.coord" port
  [ "$k" = load-sealed ] && tok=(--token-file "$out/token")
  /usr/bin/time -f "%U %S" -o "$out/$k.time" "$bin/tessera" render "$scene" --listen 127.0.0.1:0 --workers 0 \
    --width 2048 --height 2048 --spp 1 --tile-size 16 --no-progress "${tok[@]}" -o "$out/$k.pfm" > "$log" 2>&1 &
  local coord=$!
  for _ in $(seq 400); do grep -q "listening on" "$log" 2>/dev/null && break; sleep 0.05; done
  port=$(sed -n 's/.*listening on 127.0.0.1:\([0-9]*\).*/\1/p' "$log")
  "$bin/loadgen" --connect "127.0.0.1:$port" --connections "$conns" "${tok[@]}" > "$out/$k.load" 2>&1 &
  local lg=$!
  wait "$coord" || { echo "load test $k: the coordinator failed: $(tail -3 "$log")" >&2; kill "$lg"; return 1; }
  kill "$lg" 2>/dev/null || true
  wait "$lg" 2>/dev/null || true
  local tps cpu
  tps=$(sed -n 's/.*: \([0-9]*\) tiles\/s.*/\1/p' "$out/$k.load")
  cpu=$(awk '{print $1 + $2}' "$out/$k.time")
  echo "$tps $cpu"
}
median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
echo "== $scene, $spp spp, tiles $tile, $workers local workers, $rounds rounds interleaved"
for r in $(seq "$rounds"); do
  for k in "${order[@]}"; do
    s=$(date +%s.%N)
    # shellcheck disable=SC2086
    /usr/bin/time -f "%U %S" -o "$out/$k.cpu" "$bin/tessera" render "$scene" --workers "$workers" --spp "$spp" \
      --tile-size "$tile" ${runs[$k]} --no-progress -o "$out/$k.pfm" > "$out/$k.$r.out" 2>&1
    e=$(date +%s.%N)
    cpu=$(awk '{print $1 + $2}' "$out/$k.cpu") # the coordinator and its local workers
    echo "$k $(echo "$e - $s" | bc) $cpu" >> "$out/times"
    echo "  round $r $k: $(echo "$e - $s" | bc) s, CPU $cpu s (load average $(loadavg))"
  done
  for k in "${loads[@]}"; do
    read -r tps cpu < <(load_once "$k")
    echo "$k $tps $cpu" >> "$out/loads"
    echo "  round $r $k: $tps tiles/s, coordinator CPU $cpu s, $conns connections (load average $(loadavg))"
  done
  for k in "${order[@]}"; do
    cmp -s "$out/${order[0]}.pfm" "$out/$k.pfm" || echo "  round $r: $k's image differs from ${order[0]}'s"
  done
done
base=$(awk -v k="${order[0]}" '$1 == k {print $2}' "$out/times" | median)
cbase=$(awk -v k="${order[0]}" '$1 == k {print $3}' "$out/times" | median)
for k in "${order[@]}"; do
  m=$(awk -v k="$k" '$1 == k {print $2}' "$out/times" | median)
  c=$(awk -v k="$k" '$1 == k {print $3}' "$out/times" | median)
  printf "%-11s median %6.2f s  (%+.1f%% against the first), CPU %6.2f s (%+.1f%%)\n" "$k" "$m" \
    "$(echo "($m / $base - 1) * 100" | bc -l)" "$c" "$(echo "($c / $cbase - 1) * 100" | bc -l)"
done
for k in "${loads[@]}"; do
  t=$(awk -v k="$k" '$1 == k {print $2}' "$out/loads" | median)
  c=$(awk -v k="$k" '$1 == k {print $3}' "$out/loads" | median)
  printf "%-11s median %6d tiles/s, coordinator CPU %5.2f s\n" "$k" "$t" "$c"
done
