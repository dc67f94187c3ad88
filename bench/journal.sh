#!/usr/bin/env bash
# journal.sh - tiles/s of the load test through the job service, with its
# tile journal on (every tile synced before it counts): tessera-coordinator
# on a data dir, loadgen's N simulated workers answering instantly, and one
# submitted job of 2048x2048 at 1 spp in 16x16 tiles (16384 tiles), timed
# from submit to done.
#
#   bench/journal.sh [ROUNDS] [CONNECTIONS] [DATA_PARENT]
set -euo pipefail
rounds=${1:-3}; n=${2:-100}; parent=${3:-${TMPDIR:-/tmp}}
bin=${BIN:-build/release/bin}
scene=scenes/cornell-box.json
[ -x "$bin/loadgen" ] && [ -x "$bin/tessera" ] || { echo "build first: make all build/release/bin/loadgen" >&2; exit 2; }
for r in $(seq "$rounds"); do
  dir=$(mktemp -d "$parent/tessera-journal.XXXXXX")
  "$bin/tessera-coordinator" --listen 127.0.0.1:0 --data-dir "$dir/data" > "$dir/coord.log" 2>&1 &
  coord=$!
  for _ in $(seq 200); do grep -q "listening on" "$dir/coord.log" 2>/dev/null && break; sleep 0.05; done
  port=$(sed -n 's/.*listening on 127.0.0.1:\([0-9]*\).*/\1/p' "$dir/coord.log")
  "$bin/loadgen" --connect "127.0.0.1:$port" --connections "$n" > "$dir/loadgen.out" 2>&1 &
  lg=$!
  sleep 1
  t0=$(date +%s.%N)
  # bounded: simulated workers the coordinator refuses (loadgen from another build) would leave it waiting
  TESSERA_COORDINATOR=127.0.0.1:$port timeout 300 "$bin/tessera" submit "$scene" --width 2048 --height 2048 --spp 1 \
    --tile-size 16 --wait -o "$dir/out.pfm" > "$dir/submit.out" 2>&1 || {
    tail -3 "$dir/submit.out"; grep -m1 refused "$dir/coord.log" || true
    echo "journal.sh: the job did not finish within 300 s" >&2
    kill "$lg" "$coord" 2>/dev/null || true; exit 1; }
  t1=$(date +%s.%N)
  kill "$lg" 2>/dev/null || true; kill "$coord"; wait "$coord" 2>/dev/null || true; wait "$lg" 2>/dev/null || true
  awk -v a="$t0" -v b="$t1" -v r="$r" -v n="$n" 'BEGIN { printf "round %d: %d connections, 16384 tiles in %.2f s: %.0f tiles/s\n", r, n, b - a, 16384 / (b - a) }'
  grep -E "stall|journal" "$dir/coord.log" | tail -2 || true
  rm -rf "$dir"
done
