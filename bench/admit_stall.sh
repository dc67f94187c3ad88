#!/usr/bin/env bash
# admit_stall.sh - how long the job service's loop stalls when a job that
# waited for memory after a restart is admitted (README "Memory budget"):
# a 4096x4096 job journals 80 of its 256 tiles (a worker held after 80,
# TESSERA_TEST_HOLD_*), the coordinator is killed -9 and restarted with
# --max-memory 500M, room for one of the two jobs; the other is cancelled,
# this one admitted (its scene read and its 63 MB journal replayed), and
# the loop's longest iteration since the restart is printed from `tessera
# status --json` (wall and CPU ms). Not asserted.
# With MODE "startup" the restart has room for both jobs, which resume at
# once: printed are the time from starting the coordinator to its first
# answered `tessera status` and the longest iteration since (the journals
# of jobs resumed at start-up are replayed on the pool since 2026-11-27;
# before, on the loop before it served anyone).
#
# usage: bench/admit_stall.sh BIN_DIR [PORT] [admit|startup]
set -uo pipefail
B=$1 P=${2:-7311} MODE=${3:-admit}
A=127.0.0.1:$P
D=$(mktemp -d)
trap 'kill $C $W 2>/dev/null; wait 2>/dev/null; rm -rf "$D"' EXIT
export TESSERA_COORDINATOR=$A
S=$(cd "$(dirname "$0")/.." && pwd)/tests/scenes/cornell-small.json
F=(--width 4096 --height 4096 --spp 1 --tile-size 256)
"$B/tessera-coordinator" --data-dir "$D" --listen "$A" > "$D/c1.log" 2>&1 & C=$!
sleep 0.5
"$B/tessera" submit "$S" "${F[@]}" -q > /dev/null && "$B/tessera" submit "$S" "${F[@]}" --priority 5 -q > /dev/null ||
  { echo "submit failed: $D/c1.log" >&2; exit 1; }
touch "$D/hold"
TESSERA_TEST_HOLD_FILE=$D/hold TESSERA_TEST_HOLD_AFTER=80 "$B/tessera-worker" --connect "$A" --threads 2 --name w \
  --retry-max 1 > "$D/w.log" 2>&1 & W=$!
for _ in $(seq 600); do
  d=$("$B/tessera" status 2 --json | grep -o '"tiles_done":[^,]*' | tr -dc 0-9)
  [ "$d" = 80 ] && break
  sleep 0.1
done
[ "$d" = 80 ] || { echo "job 2 has $d tiles, not 80" >&2; exit 1; }
kill -9 $C $W; wait 2>/dev/null
if [ "$MODE" = startup ]; then
  t0=$(date +%s.%N)
  "$B/tessera-coordinator" --data-dir "$D" --listen "$A" > "$D/c2.log" 2>&1 & C=$!
  for _ in $(seq 3000); do "$B/tessera" status > /dev/null 2>&1 && break; sleep 0.005; done
  t1=$(date +%s.%N)
  for _ in $(seq 300); do grep -q 'job 2 resumed' "$D/c2.log" && break; sleep 0.05; done
  sleep 0.5
  grep -o 'job 2 resumed.*' "$D/c2.log"
  echo "journal: $(stat -c %s "$D/jobs/2.tiles") bytes; first status answered $(echo "($t1 - $t0) * 1000" | bc) ms after the start"
  "$B/tessera" status --json | grep -o '"longest_stall[a-z_]*":[^,}]*' | tr -d '\t' | tr '\n' ' '
  echo
  exit 0
fi
"$B/tessera-coordinator" --data-dir "$D" --listen "$A" --max-memory 500M > "$D/c2.log" 2>&1 & C=$!
sleep 1
"$B/tessera" cancel 1 > /dev/null
for _ in $(seq 300); do grep -q 'job 2 resumed' "$D/c2.log" && break; sleep 0.05; done
sleep 0.5
grep -o 'job 2 resumed.*' "$D/c2.log"
echo "journal: $(stat -c %s "$D/jobs/2.tiles") bytes"
"$B/tessera" status --json | grep -o '"longest_stall[a-z_]*":[^,}]*' | tr -d '\t' | tr '\n' ' '
echo
