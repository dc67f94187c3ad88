#!/bin/bash
# sigload.sh - how long a worker told to leave (SIGTERM) while it loads a
# scene takes to exit. A coordinator (--max-upload 512) and one worker (2
# threads, -v) on 127.0.0.1:7311, SCENE submitted at 1 spp, SIGTERM DELAY
# seconds after the worker logs the job; prints the time to exit and the
# worker's last line about the scene ("cancelled", or "loaded ... in T s"
# when the load was finished first).
# Usage: bench/sigload.sh BUILD/bin SCENE DELAY
set -u
B=$1 S=$2 D=$3
W=$(mktemp -d /tmp/tessera-sigload.XXXXXX)
"$B/tessera" coordinator --data-dir "$W/data" --listen 127.0.0.1:7311 --max-upload 512 > "$W/c.log" 2>&1 &
CP=$!
sleep 0.5
"$B/tessera-worker" --connect 127.0.0.1:7311 --threads 2 -v > "$W/w.log" 2>&1 &
WP=$!
sleep 0.5
TESSERA_COORDINATOR=127.0.0.1:7311 "$B/tessera" submit "$S" --spp 1 -q > /dev/null
for _ in $(seq 1 400); do grep -q "job 1: scene" "$W/w.log" && break; sleep 0.02; done
sleep "$D"
t0=$(date +%s.%N)
kill -TERM $WP
wait $WP
t1=$(date +%s.%N)
echo "SIGTERM $D s into the job: left after $(echo "$t1 - $t0" | bc) s: $(grep -o 'job 1: scene [0-9a-f]*[: ].*' "$W/w.log" | tail -1 | cut -c1-140)"
kill $CP
wait $CP 2> /dev/null
rm -rf "$W"
