#!/usr/bin/env bash
# containers.sh - a 4-worker container pool (docker/compose.yaml) against 4
# local worker processes, the same job on the same machine, rounds
# interleaved; and the bytes per tile the coordinator container receives.
#
#   bench/containers.sh [ROUNDS] [SIZE] [SPP]      (default 5 256 32)
#
# Both set-ups are the job service: a coordinator (in a container, or a
# process on the host) and 4 workers of 1 thread each; the time is that of
# `tessera submit --wait` (upload, render, fetch). Needs `make` and
# `make docker`. Prints a table; cleans up its Compose project.
set -uo pipefail
cd "$(dirname "$0")/.."
ROUNDS=${1:-5} SIZE=${2:-256} SPP=${3:-32}
BIN=build/release/bin
SCENE=scenes/cornell-box.json
PROJECT=tesserabench$$
WORK=$(mktemp -d /tmp/tessera-bench-containers.XXXXXX)
if command -v docker-compose > /dev/null; then COMPOSE=(docker-compose); else COMPOSE=(docker compose); fi
port() { local p; while :; do p=$((20000 + RANDOM % 40000)); ss -ltnH "sport = :$p" | grep -q . || { echo "$p"; return; }; done; }
CPORT=$(port) LPORT=$(port)
head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \n' > "$WORK/token"; chmod 0444 "$WORK/token"
export TESSERA_PORT=$CPORT TESSERA_TOKEN_FILE=$WORK/token TESSERA_WORKER_THREADS=1
dc() { "${COMPOSE[@]}" -p "$PROJECT" -f docker/compose.yaml "$@" > /dev/null 2>&1; }
pids=()
cleanup() {
    dc down -v -t 3
    for p in "${pids[@]}"; do kill "$p" 2> /dev/null; done
    wait 2> /dev/null
    rm -rf "$WORK"
}
trap cleanup EXIT

dc up -d --scale worker=4
mkdir -p "$WORK/data"
"$BIN/tessera-coordinator" --listen "127.0.0.1:$LPORT" --data-dir "$WORK/data" --token-file "$WORK/token" \
    > "$WORK/coord.log" 2>&1 &
pids+=($!)
for i in 1 2 3 4; do
    "$BIN/tessera-worker" --connect "127.0.0.1:$LPORT" --token-file "$WORK/token" --threads 1 -q \
        > "$WORK/worker$i.log" 2>&1 &
    pids+=($!)
done
wait_n() { # wait_n PORT: until 4 workers are connected
    for _ in $(seq 300); do
        "$BIN/tessera" status --coordinator "127.0.0.1:$1" 2> /dev/null | grep -q "^4 workers" && return 0
        sleep 0.2
    done
    echo "error: 4 workers never connected on $1" >&2; exit 1
}
wait_n "$CPORT"; wait_n "$LPORT"
# job PORT OUT: print the seconds of one submit --wait.
job() {
    local t0 t1
    t0=$(date +%s.%N)
    "$BIN/tessera" submit "$SCENE" --coordinator "127.0.0.1:$1" --width "$SIZE" --height "$SIZE" --spp "$SPP" \
        --wait -o "$2" > /dev/null 2>&1 || { echo "error: job on port $1 failed" >&2; exit 1; }
    t1=$(date +%s.%N)
    awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.2f\n", b - a }'
}
coord=$(docker ps -q --filter "label=com.docker.compose.project=$PROJECT" --filter "label=com.docker.compose.service=coordinator")
rx() { docker exec "$coord" cat /sys/class/net/eth0/statistics/rx_bytes; }
tiles=$(( ((SIZE + 31) / 32) * ((SIZE + 31) / 32) ))
echo "cornell-box ${SIZE}x${SIZE}, $SPP spp, $tiles tiles of 32x32; 4 workers of 1 thread; $ROUNDS rounds interleaved"
: > "$WORK/c"; : > "$WORK/l"
for r in $(seq "$ROUNDS"); do
    b0=$(rx)
    c=$(job "$CPORT" "$WORK/c$r.pfm"); echo "$c" >> "$WORK/c"
    b1=$(rx)
    l=$(job "$LPORT" "$WORK/l$r.pfm"); echo "$l" >> "$WORK/l"
    cmp -s "$WORK/c$r.pfm" "$WORK/l$r.pfm" && same=same || same=DIFFERENT
    echo "round $r: containers $c s, processes $l s, images $same; coordinator container received $(( (b1 - b0) / tiles )) bytes per tile"
done
median() { sort -n "$1" | awk '{ a[NR] = $1 } END { print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2 }'; }
mc=$(median "$WORK/c"); ml=$(median "$WORK/l")
echo "median: containers $mc s, processes $ml s, containers/processes $(awk -v a="$mc" -v b="$ml" 'BEGIN { printf "%.3f", a / b }')"
