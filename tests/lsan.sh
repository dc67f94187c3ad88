#!/usr/bin/env bash
# lsan.sh - the load test, worker churn and every client request against an
# ASan build's coordinator with LeakSanitizer on: any leak (or other ASan
# report) in the coordinator, a worker, loadgen or a client fails the run.
#
#   tests/lsan.sh BIN_DIR [LOAD_SECONDS]     (BIN_DIR: build/asan/bin)
#
# Every process writes its report to REPORTS/asan.PID (ASAN_OPTIONS
# log_path), so a leak is caught whoever started the process and whatever
# its log; the run fails when that folder is not empty at the end.
set -euo pipefail
bin=${1:?usage: tests/lsan.sh BIN_DIR [LOAD_SECONDS]}
secs=${2:-10}
dir=$(mktemp -d "${TMPDIR:-/tmp}/tessera-lsan.XXXXXX")
reports=$dir/reports
mkdir -p "$reports"
export ASAN_OPTIONS=detect_leaks=1:log_path=$reports/asan
export TESSERA_CLIENT_TIMEOUT=120
pids=()
# On any failure: stop what is left and show the reports (a leak makes a
# process exit non-zero, so the first check to fail may be an exit status).
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2> /dev/null || true; done
  if compgen -G "$reports/*" > /dev/null; then
    echo "lsan: FAILED: sanitizer reports ($(ls "$reports" | wc -l) processes):" >&2
    head -60 "$reports"/* >&2
  fi
}
trap cleanup EXIT
t0=$(date +%s)

TESSERA_FETCH_CHUNK=65536 "$bin/tessera-coordinator" --listen 127.0.0.1:0 --data-dir "$dir/data" --heartbeat 0.5 --worker-timeout 10 \
  > "$dir/coord.log" 2>&1 &
coord=$!
pids+=("$coord")
for _ in $(seq 600); do grep -q "listening on" "$dir/coord.log" 2> /dev/null && break; sleep 0.1; done
port=$(sed -n 's/.*listening on 127.0.0.1:\([0-9]*\).*/\1/p' "$dir/coord.log")
[ -n "$port" ] || { echo "lsan: the coordinator did not start: $(cat "$dir/coord.log")" >&2; exit 1; }
export TESSERA_COORDINATOR=127.0.0.1:$port
tessera=$bin/tessera

# The load test: simulated workers answering every tile (black) while a job
# of many small tiles runs, then cancelled. loadgen stays to the end: it
# exits (and LeakSanitizer looks) when the coordinator closes its links.
"$bin/loadgen" --connect "127.0.0.1:$port" --connections 50 > "$dir/loadgen.out" 2>&1 &
lg=$!
pids+=("$lg")
"$tessera" submit scenes/cornell-box.json --width 2048 --height 2048 --spp 1 --tile-size 16 > "$dir/submit.out"
sleep "$secs"
"$tessera" status > /dev/null
"$tessera" workers > /dev/null
"$tessera" fetch 1 --partial -o "$dir/partial.pfm" > /dev/null 2>&1
"$tessera" cancel 1 > /dev/null 2>&1 || true # (done already on a fast host)

# Real workers arriving and leaving (the hello/close cycle that leaked),
# one killed mid-job; a job finished and fetched through the chunked stream.
for i in 1 2 3 4 5 6; do
  "$bin/tessera-worker" --connect "127.0.0.1:$port" --threads 1 --name "churn-$i" --retry-max 1 > "$dir/w$i.log" 2>&1 &
  w=$!
  sleep 1
  kill -TERM "$w"
  wait "$w" || { echo "lsan: worker churn-$i exited $?: $(tail -3 "$dir/w$i.log")" >&2; exit 1; }
done
"$bin/tessera-worker" --connect "127.0.0.1:$port" --threads 2 --name steady --retry-max 1 > "$dir/steady.log" 2>&1 &
steady=$!
pids+=("$steady")
"$bin/tessera-worker" --connect "127.0.0.1:$port" --threads 1 --name doomed --retry-max 1 > "$dir/doomed.log" 2>&1 &
doomed=$!
"$tessera" submit tests/scenes/cornell-small.json --spp 4 --tile-size 16 --wait -o "$dir/done.png" > "$dir/wait.out" 2>&1 &
sub=$!
sleep 2
kill -9 "$doomed" 2> /dev/null || true
wait "$doomed" 2> /dev/null || true
wait "$sub" || { echo "lsan: submit --wait failed: $(cat "$dir/wait.out")" >&2; exit 1; }
"$tessera" fetch 2 -o "$dir/done.pfm" > /dev/null
"$tessera" status 99 > /dev/null 2>&1 || true # an error answer
kill -TERM "$steady"
wait "$steady" || { echo "lsan: worker steady exited $?" >&2; exit 1; }

kill -TERM "$coord"
wait "$coord" || { echo "lsan: the coordinator exited $? on SIGTERM; log $dir/coord.log" >&2; exit 1; }
wait "$lg" || { echo "lsan: loadgen exited $?: $(cat "$dir/loadgen.out")" >&2; exit 1; }
compgen -G "$reports/*" > /dev/null && exit 1 # (cleanup prints them)
trap - EXIT
echo "lsan: no leaks (coordinator, loadgen, workers, clients) in $(($(date +%s) - t0)) s; $(cat "$dir/loadgen.out")"
rm -rf "$dir"
