#!/usr/bin/env bash
# soak.sh - the coordinator under everything at once for a set time (`make
# soak`, minutes, not in CI): the load test (loadgen's simulated workers on
# a job of many small tiles), hostile clients (bench/soak_hostile.py: idle,
# trickled uploads, an oversized frame, bad numbers, garbage), and real
# workers killed with -9 while checked jobs render. One coordinator and one
# data dir throughout; cycles of a load phase and a real-worker phase (the
# simulated workers answer black tiles, so checked jobs render without them)
# with the hostile clients running through both.
#
#   bench/soak.sh BIN_DIR SECONDS
#
# Reports: jobs completed (load and checked), checked images identical to an
# in-process render, the longest loop iteration (wall and CPU, from status),
# the coordinator's peak RSS, and its open descriptors at the start and the
# end (after every client and worker has gone).
set -euo pipefail
bin=${1:?usage: bench/soak.sh BIN_DIR SECONDS}
secs=${2:-300}
scene=tests/scenes/cornell-small.json
size=(--width 128 --height 128 --spp 4)
dir=$(mktemp -d "${TMPDIR:-/tmp}/tessera-soak.XXXXXX")
pids=()
cleanup() { for p in "${pids[@]}"; do kill -9 "$p" 2> /dev/null || true; done; }
trap cleanup EXIT
build="$(sed -n 's/.*TESSERA_VERSION "\(.*\)".*/\1/p' common/version.h)+$(sed -n 's/.*"\(.*\)".*/\1/p' "$bin/../build_id.h")"

"$bin/tessera" render "$scene" "${size[@]}" --workers 0 -o "$dir/ref.pfm" > /dev/null 2>&1
"$bin/tessera-coordinator" --listen 127.0.0.1:0 --data-dir "$dir/data" --heartbeat 0.5 --worker-timeout 3 \
  --client-timeout 5 --max-upload 1 --keep-jobs 50 > "$dir/coord.log" 2>&1 &
coord=$!
pids+=("$coord")
for _ in $(seq 300); do grep -q "listening on" "$dir/coord.log" 2> /dev/null && break; sleep 0.1; done
port=$(sed -n 's/.*listening on 127.0.0.1:\([0-9]*\).*/\1/p' "$dir/coord.log")
export TESSERA_COORDINATOR=127.0.0.1:$port TESSERA_CLIENT_TIMEOUT=60
sleep 1
fd_start=$(ls /proc/$coord/fd | wc -l)
rss_start=$(awk '/VmRSS/ {print $2}' /proc/$coord/status)
python3 bench/soak_hostile.py 127.0.0.1 "$port" "$build" 5 | grep -q "idle_opened 20" \
  || { echo "soak: the hostile clients could not speak to the coordinator (build id $build?)" >&2; exit 1; }

end=$(($(date +%s) + secs))
(while [ "$(date +%s)" -lt "$end" ]; do python3 bench/soak_hostile.py 127.0.0.1 "$port" "$build" 15 || true; done) \
  > "$dir/hostile.out" 2>&1 &
hostile=$!
pids+=("$hostile")

load_jobs=0 checked=0 identical=0 kills=0 cycle=0 load_tiles=0
rates=()
job_of() { sed -n 's/.*job \([0-9]*\).*/\1/p' | head -1; }
while [ "$(date +%s)" -lt "$end" ]; do
  cycle=$((cycle + 1))
  # Load phase: 100 simulated workers, one job of 4096 tiles of 16x16.
  "$bin/loadgen" --connect "127.0.0.1:$port" --connections 100 > "$dir/loadgen.$cycle" 2>&1 &
  lg=$!
  pids+=("$lg")
  sleep 0.5
  t0=$(date +%s.%N)
  if "$bin/tessera" submit "$scene" --width 1024 --height 1024 --spp 1 --tile-size 16 --wait -o "$dir/load.pfm" \
    > "$dir/load.out" 2>&1; then
    load_jobs=$((load_jobs + 1))
    load_tiles=$((load_tiles + 4096))
    rates+=("$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.0f", 4096 / (b - a) }')")
  else
    echo "soak: load job failed: $(tail -2 "$dir/load.out")" >&2
  fi
  kill -TERM "$lg" 2> /dev/null || true
  wait "$lg" 2> /dev/null || true
  # Real phase: three workers, three checked jobs, a worker killed -9 every 2 s and replaced.
  ws=()
  for i in 1 2 3; do
    "$bin/tessera-worker" --connect "127.0.0.1:$port" --threads 1 --name "soak-$cycle-$i" --retry-max 1 \
      > /dev/null 2>&1 &
    ws+=($!)
  done
  subs=()
  for k in 1 2 3; do
    "$bin/tessera" submit "$scene" "${size[@]}" --tile-size 16 --wait -o "$dir/c$k.pfm" > "$dir/c$k.out" 2>&1 &
    subs+=($!)
  done
  for t in 1 2 3 4; do
    sleep 2
    v=$((RANDOM % 3))
    kill -9 "${ws[$v]}" 2> /dev/null && kills=$((kills + 1))
    wait "${ws[$v]}" 2> /dev/null || true
    "$bin/tessera-worker" --connect "127.0.0.1:$port" --threads 1 --name "soak-$cycle-r$t" --retry-max 1 \
      > /dev/null 2>&1 &
    ws[$v]=$!
  done
  for k in 1 2 3; do
    if wait "${subs[$((k - 1))]}"; then
      checked=$((checked + 1))
      cmp -s "$dir/c$k.pfm" "$dir/ref.pfm" && identical=$((identical + 1))
    else
      echo "soak: checked job failed: $(tail -2 "$dir/c$k.out")" >&2
    fi
  done
  for w in "${ws[@]}"; do kill -TERM "$w" 2> /dev/null || true; wait "$w" 2> /dev/null || true; done
done
wait "$hostile" || true
sleep 6 # past --client-timeout: the last idle clients are closed
st=$("$bin/tessera" status --json)
stall=$(echo "$st" | sed -n 's/.*"longest_stall_ms":[[:space:]]*\([0-9.]*\).*/\1/p' | head -1)
stall_cpu=$(echo "$st" | sed -n 's/.*"longest_stall_cpu_ms":[[:space:]]*\([0-9.]*\).*/\1/p' | head -1)
fd_end=$(ls /proc/$coord/fd | wc -l)
rss_end=$(awk '/VmRSS/ {print $2}' /proc/$coord/status)
hwm=$(awk '/VmHWM/ {print $2}' /proc/$coord/status)
kill -TERM "$coord"
wait "$coord" || echo "soak: the coordinator exited $? on SIGTERM" >&2
trap - EXIT
rounds=$(grep -c '^hostile:' "$dir/hostile.out" || true)
echo "soak: ${secs} s, $cycle cycles, load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "  jobs completed: $load_jobs load-test jobs ($load_tiles tiles from 100 simulated workers), $checked checked jobs"
echo "  images identical to the in-process render: $identical of $checked; workers killed -9: $kills"
echo "  hostile rounds: $rounds; last: $(grep '^hostile:' "$dir/hostile.out" | tail -1)"
echo "  longest loop iteration: ${stall} ms wall, ${stall_cpu} ms CPU"
echo "  coordinator: peak RSS $hwm KiB (RSS $rss_start KiB at the start, $rss_end at the end); open descriptors $fd_start at the start, $fd_end at the end"
echo "  load jobs, tiles/s from submit to done (fetch included): ${rates[*]:-none}"
[ "$identical" -eq "$checked" ] && [ "$checked" -gt 0 ] && [ "$fd_end" -le "$fd_start" ] || { echo "soak: FAILED (log: $dir)"; exit 1; }
rm -rf "$dir"
