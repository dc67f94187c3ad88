#!/usr/bin/env bash
# run.sh - `make docker-test`: Tessera's container pools against the real
# Docker engine. Every test renders through containers and compares the image
# byte for byte (PFM, float) with `tessera render --workers 0` of the same
# scene, size, spp and seed on the host:
#   1 a Compose pool of 3 workers, `tessera submit --wait` from the host
#   2 faults: docker kill, docker pause past the worker timeout, docker network
#     disconnect + connect, one per job; prints what each cost against a job
#     without faults
#   3 the coordinator container killed mid-job and started again on its
#     volume: resumes from the journal, no journaled tile rendered again
#   4 scale up to 6 workers and down to 2 mid-job
#   5 one build id for the same build; a worker from another build refused
#     with both ids named
#   6 Swarm: docker stack deploy (docker/stack.yaml), 3 replicas, service scale
#     mid-job (a one-node swarm made for the test when the engine is in none)
#   7 wrong and missing token in a worker container (and a client): refused,
#     logged, nothing rendered
# Ends with "N passed, N failed" (exit status 1 when any failed). Everything
# it makes (containers, networks, volumes, secrets, images, the swarm) is
# removed on exit, also after a failure or ^C. Needs the image (`make docker`,
# which `make docker-test` runs first) and the host's build/release/bin.
#
#   tests/docker/run.sh [TEST...]      # e.g. tests/docker/run.sh 1 3
set -uo pipefail
cd "$(dirname "$0")/../.."

BIN=${TESSERA_BIN_DIR:-build/release/bin}
T=$BIN/tessera
IMAGE=${TESSERA_IMAGE:-tessera:latest}
GIT_ID=${GIT_ID:-$(docker image inspect -f '{{index .Config.Labels "io.tessera.build-id"}}' "$IMAGE" 2>/dev/null)}
SCENE=scenes/cornell-box.json
ID=tt$$                       # names everything this run makes
PROJECT=tesseratest$$         # the Compose project
STACK=tesseraswarm$$          # the Swarm stack
TIMEOUT=3                     # --worker-timeout of the coordinator, seconds
export TESSERA_TEST_THROTTLE_MS=250
TESTS=${*:-1 2 3 4 5 7 6}   # 6 last: it takes the Compose pool down
PASS=0 FAIL=0
SWARM_MADE=0 GWBRIDGE_MADE=0 STACK_UP=0 NODE_LABELLED=""

[ -x "$T" ] || { echo "error: $T missing (make)" >&2; exit 1; }
docker info > /dev/null 2>&1 || { echo "error: no Docker engine answers (docker info)" >&2; exit 1; }
docker image inspect "$IMAGE" > /dev/null 2>&1 || { echo "error: no image $IMAGE (make docker)" >&2; exit 1; }
if command -v docker-compose > /dev/null; then COMPOSE=(docker-compose)
elif docker compose version > /dev/null 2>&1; then COMPOSE=(docker compose)
else echo "error: neither docker-compose nor docker compose" >&2; exit 1; fi

WORK=$(mktemp -d /tmp/tessera-docker-test.XXXXXX)
LOG=$WORK/log
: > "$LOG"

# free_port: a TCP port nothing listens on.
free_port() {
    local p
    for _ in $(seq 100); do
        p=$((20000 + RANDOM % 40000))
        ss -ltnH "sport = :$p" 2>/dev/null | grep -q . || { echo "$p"; return 0; }
    done
    return 1
}
PORT=$(free_port)
export TESSERA_PORT=$PORT TESSERA_TOKEN_FILE=$WORK/token TESSERA_WORKER_TIMEOUT=$TIMEOUT TESSERA_IMAGE=$IMAGE
export TESSERA_COORDINATOR=127.0.0.1:$PORT
head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \n' > "$WORK/token"
chmod 0444 "$WORK/token" # the containers' uid 10001 reads it (a bind mount keeps the mode)
NET=${PROJECT}_default

dc() { "${COMPOSE[@]}" -p "$PROJECT" -f docker/compose.yaml -f tests/docker/compose.test.yaml "$@" >> "$LOG" 2>&1; }
coord() { docker ps -q --filter "label=com.docker.compose.project=$PROJECT" --filter "label=com.docker.compose.service=coordinator"; }
workers() { docker ps -q --filter "label=com.docker.compose.project=$PROJECT" --filter "label=com.docker.compose.service=worker"; }
clog() { local c; c=$(docker ps -aq --filter "label=com.docker.compose.project=$PROJECT" --filter "label=com.docker.compose.service=coordinator" | head -1); [ -n "$c" ] && docker logs "$c" 2>&1; }
now() { date +%s.%N; }
secs() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", b - a }'; }

cleanup() {
    set +e
    trap - EXIT INT TERM
    if [ "$STACK_UP" = 1 ]; then
        docker stack rm "$STACK" >> "$LOG" 2>&1
        for _ in $(seq 60); do
            [ -z "$(docker ps -aq --filter "label=com.docker.stack.namespace=$STACK")" ] &&
                [ -z "$(docker network ls -q --filter "label=com.docker.stack.namespace=$STACK")" ] && break
            sleep 1
        done
        docker volume ls -q --filter "label=com.docker.stack.namespace=$STACK" | xargs -r docker volume rm >> "$LOG" 2>&1
    fi
    [ -n "$NODE_LABELLED" ] && docker node update --label-rm tessera.coordinator "$NODE_LABELLED" >> "$LOG" 2>&1
    if [ "$SWARM_MADE" = 1 ]; then
        docker swarm leave --force >> "$LOG" 2>&1
        # swarm init made this bridge when it was not there; leave does not remove it.
        [ "$GWBRIDGE_MADE" = 1 ] && docker network rm docker_gwbridge >> "$LOG" 2>&1
    fi
    "${COMPOSE[@]}" -p "$PROJECT" -f docker/compose.yaml -f tests/docker/compose.test.yaml down -v --remove-orphans -t 3 >> "$LOG" 2>&1
    docker ps -aq --filter "label=io.tessera.test=$ID" | xargs -r docker rm -f >> "$LOG" 2>&1
    # By tag, never by id: the image built again has tessera:latest's id.
    docker images --format '{{.Repository}}:{{.Tag}}' --filter "reference=tessera-$ID" | xargs -r docker rmi >> "$LOG" 2>&1
    # The other build's compile stage is left dangling: its id is in its log.
    [ -f "$WORK/build-other.log" ] && awk '/^Step .*RUN make -j/ { f = 1; next } f && /^ ---> [0-9a-f]+$/ { print $2; exit }' \
        "$WORK/build-other.log" | xargs -r docker rmi >> "$LOG" 2>&1
    left=$(docker ps -aq --filter "label=io.tessera.test=$ID" --filter "label=com.docker.compose.project=$PROJECT")
    [ -n "$left" ] && echo "warning: containers left: $left"
    if [ "$FAIL" -gt 0 ] || [ -n "${TESSERA_DOCKER_TEST_KEEP:-}" ]; then echo "logs kept in $WORK"; else rm -rf "$WORK"; fi
}
trap cleanup EXIT
trap 'echo "interrupted"; exit 130' INT TERM

ok() { PASS=$((PASS + 1)); echo "ok   $1"; }
fail() { FAIL=$((FAIL + 1)); echo "FAIL $1"; }
# check NAME COND-STATUS MESSAGE: count a test's result.
check() { if [ "$2" -eq 0 ]; then ok "$1"; else fail "$1: $3"; fi; }

# ref W H SPP SEED: print the path of the reference render (made once).
ref() {
    local f=$WORK/ref-$1x$2-$3-$4.pfm
    [ -f "$f" ] || nice -n 10 "$T" render "$SCENE" --workers 0 --width "$1" --height "$2" --spp "$3" --seed "$4" \
        --no-progress -o "$f" >> "$LOG" 2>&1
    echo "$f"
}
# submit W H SPP SEED [options]: submit the scene; prints the job number.
submit() {
    local w=$1 h=$2 spp=$3 seed=$4; shift 4
    "$T" submit "$SCENE" --width "$w" --height "$h" --spp "$spp" --seed "$seed" --json "$@" 2>> "$LOG" |
        sed -n 's/.*"job": *\([0-9]*\).*/\1/p' | head -1
}
# job_field JOB N: field N of the job's `tessera status` line (2 state, 4 done/total).
job_field() { "$T" status "$1" 2>> "$LOG" | awk -v j="$1" -v n="$2" '$1 == j { print $n }'; }
tiles_done() { local t; t=$(job_field "$1" 4); echo "${t%%/*}"; }
# wait_job JOB SECONDS: 0 when the job is done within SECONDS.
wait_job() {
    local end=$((SECONDS + $2)) s
    while [ $SECONDS -lt $end ]; do
        s=$(job_field "$1" 2)
        [ "$s" = done ] && return 0
        [ "$s" = failed ] || [ "$s" = cancelled ] && return 1
        sleep 0.2
    done
    return 1
}
# wait_tiles JOB N SECONDS: 0 when at least N tiles of JOB are done.
wait_tiles() {
    local end=$((SECONDS + $3)) d
    while [ $SECONDS -lt $end ]; do
        d=$(tiles_done "$1"); [ -n "$d" ] && [ "$d" -ge "$2" ] && return 0
        sleep 0.1
    done
    return 1
}
# wait_workers N SECONDS: 0 when the coordinator has N workers connected.
wait_workers() {
    local end=$((SECONDS + $2)) n
    while [ $SECONDS -lt $end ]; do
        n=$("$T" status 2>> "$LOG" | sed -n 's/^\([0-9]*\) workers* connected.*/\1/p')
        [ "${n:-0}" -eq "$1" ] && return 0
        sleep 0.2
    done
    return 1
}
# same A B: 0 when the two files are byte-identical (the message says why not).
same() { cmp "$1" "$2" >> "$LOG" 2>&1; }
# run_worker NAME IMAGE [args]: a worker container outside Compose on the pool's network.
run_worker() {
    local name=$1 img=$2; shift 2
    docker run -d --label "io.tessera.test=$ID" --name "$ID-$name" --network "$NET" --read-only \
        -v "$WORK/token:/run/secrets/tessera_token:ro" "$img" --connect coordinator:7000 \
        --token-file /run/secrets/tessera_token --name "$name" "$@"
}

echo "docker-test: image $IMAGE (build $GIT_ID), Compose project $PROJECT on 127.0.0.1:$PORT, ${COMPOSE[*]}"
dc up -d --scale worker=0 || { fail "compose up: $(tail -3 "$LOG")"; exit 1; }
BASELINE=""

# ---- 1: a pool of 3 ----------------------------------------------------------
test1() {
    local r job t0 t1 out=$WORK/t1.pfm
    r=$(ref 256 256 4 11)
    # A worker container's start to its first tile, with a job waiting.
    job=$(submit 256 256 4 11)
    t0=$(now)
    run_worker first "$IMAGE" --threads 1 > /dev/null
    wait_tiles "$job" 1 60; t1=$(now)
    echo "     a worker container from docker run to its first tile: $(secs "$t0" "$t1") s"
    docker stop -t 10 "$ID-first" > /dev/null
    local st; st=$(docker inspect -f '{{.State.ExitCode}}' "$ID-first")
    check "1a worker container stopped (SIGTERM) exits 0" "$([ "$st" = 0 ]; echo $?)" "exit status $st"
    "$T" cancel "$job" > /dev/null 2>> "$LOG"
    dc up -d --scale worker=3 && wait_workers 3 60
    t0=$(now)
    "$T" submit "$SCENE" --width 256 --height 256 --spp 4 --seed 11 --wait -o "$out" >> "$LOG" 2>&1
    local rc=$?; t1=$(now)
    BASELINE=$(secs "$t0" "$t1")
    check "1  Compose pool of 3, submit --wait from the host: same bytes as --workers 0 ($BASELINE s)" \
        "$([ $rc -eq 0 ] && same "$out" "$r"; echo $?)" "submit status $rc; see $LOG"
}

# ---- 2: faults ----------------------------------------------------------------
# fault_job NAME ACTION: a job on the pool of 3 with ACTION run 1.5 s in;
# checks the bytes and prints the time against the baseline.
fault_job() {
    local name=$1 action=$2 r out=$WORK/t2-$1.pfm t0 t1 pid rc
    r=$(ref 256 256 4 12)
    dc up -d --scale worker=3 && wait_workers 3 60
    t0=$(now)
    "$T" submit "$SCENE" --width 256 --height 256 --spp 4 --seed 12 --wait -o "$out" >> "$LOG" 2>&1 &
    pid=$!
    sleep 1.5
    $action
    wait "$pid"; rc=$?; t1=$(now)
    local took; took=$(secs "$t0" "$t1")
    check "2  $name mid-job: the job finishes, same bytes ($took s, $(awk -v a="$took" -v b="$BASELINE" 'BEGIN { printf "%+.1f", a - b }') s against no fault)" \
        "$([ $rc -eq 0 ] && same "$out" "$r"; echo $?)" "submit status $rc; see $LOG"
}
fault_kill() { docker kill "$(workers | head -1)" >> "$LOG"; }
fault_pause() {
    local w; w=$(workers | head -1)
    docker pause "$w" >> "$LOG"; sleep $((TIMEOUT + 2)); docker unpause "$w" >> "$LOG"
}
fault_net() {
    local w; w=$(workers | head -1)
    docker network disconnect "$NET" "$w" >> "$LOG"; sleep $((TIMEOUT + 2)); docker network connect "$NET" "$w" >> "$LOG"
}
test2() {
    local t0 t1 r=$WORK/t2-none.pfm
    dc up -d --scale worker=3 && wait_workers 3 60
    ref 256 256 4 12 > /dev/null
    t0=$(now)
    "$T" submit "$SCENE" --width 256 --height 256 --spp 4 --seed 12 --wait -o "$r" >> "$LOG" 2>&1
    t1=$(now); BASELINE=$(secs "$t0" "$t1")
    echo "     the same job without a fault: $BASELINE s"
    fault_job "docker kill of a worker" fault_kill
    fault_job "docker pause of a worker for $((TIMEOUT + 2)) s (worker timeout $TIMEOUT s)" fault_pause
    fault_job "docker network disconnect of a worker for $((TIMEOUT + 2)) s" fault_net
    dc up -d --scale worker=3
    wait_workers 3 30
    check "2  after the faults all 3 workers are connected again" $? "$("$T" status 2>&1 | tail -1)"
}

# ---- 3: the coordinator killed mid-job ----------------------------------------
test3() {
    local r job c t0 t1 out=$WORK/t3.pfm total=64
    r=$(ref 256 256 4 13)
    dc up -d --scale worker=3 && wait_workers 3 60
    job=$(submit 256 256 4 13)
    wait_tiles "$job" 20 60
    c=$(coord)
    docker kill "$c" >> "$LOG"; t0=$(now)
    sleep 1
    [ "$(docker inspect -f '{{.State.Running}}' "$c")" = true ] || docker start "$c" >> "$LOG"
    wait_job "$job" 90; t1=$(now)
    "$T" fetch "$job" -o "$out" >> "$LOG" 2>&1
    local resumed again rendered
    resumed=$(clog | sed -n "s/.*job $job resumed: \([0-9]*\) of $total tiles from the journal.*/\1/p" | tail -1)
    again=$(clog | sed -n "s/.*job $job done (\([0-9]*\) tiles from the journal.*/\1/p" | tail -1)
    rendered=$(clog | sed -n "s/.*job $job done ([0-9]* tiles from the journal, \([0-9]*\) rendered in this run.*/\1/p" | tail -1)
    echo "     kill to done: $(secs "$t0" "$t1") s; resumed ${resumed:-?} of $total tiles from the journal, ${rendered:-?} rendered after the restart"
    check "3  coordinator container killed and restarted on its volume: resumes, no journaled tile rendered again, same bytes" \
        "$([ -n "$resumed" ] && [ "$resumed" -ge 20 ] && [ "$again" = "$resumed" ] &&
           [ $((resumed + rendered)) -eq $total ] && same "$out" "$r"; echo $?)" \
        "resumed '$resumed', done with '$again' from the journal and '$rendered' rendered; see $LOG"
}

# ---- 4: scale up and down mid-job ----------------------------------------------
# worker_tiles: "NAME TILES" of every connected worker.
worker_tiles() { "$T" workers 2>> "$LOG" | awk 'NR > 1 { print $1, $4 }'; }
test4() {
    local r out=$WORK/t4.pfm pid rc t0 t1 n left0 left1 job d1 d2
    r=$(ref 576 576 4 14)
    dc up -d --scale worker=3 && wait_workers 3 60
    job=$(submit 576 576 4 14)   # 324 tiles: about 25 s on 3 workers
    sleep 1.5
    t0=$(now)
    dc up -d --no-recreate --scale worker=6
    local busy=0 end=$((SECONDS + 30))
    while [ $SECONDS -lt $end ]; do
        busy=$(worker_tiles | awk '$2 > 0' | wc -l)
        [ "$busy" -ge 6 ] && break
        sleep 0.1
    done
    t1=$(now)
    echo "     scale to 6: all 6 workers had finished a tile $(secs "$t0" "$t1") s after the scale command"
    check "4a scale up to 6 mid-job: the new workers get work" "$([ "$busy" -ge 6 ]; echo $?)" \
        "$busy of 6 workers did a tile: $(worker_tiles | tr '\n' ' ')"
    left0=$(clog | grep -c "left: worker left")
    d1=$(tiles_done "$job")
    dc up -d --no-recreate --scale worker=2
    d2=$(tiles_done "$job")
    left1=$(clog | grep -c "left: worker left")
    # Mid-job: how many said bye before the coordinator logged the job done.
    local before; before=$(clog | awk -v j="job $job done" 'index($0, j) { exit } /left: worker left/ { n++ } END { print n + 0 }')
    echo "     scale to 2 between $d1 and $d2 of 324 tiles; $((left1 - left0)) workers said bye, $((before - left0)) before the job ended"
    wait_job "$job" 120 && "$T" fetch "$job" -o "$out" >> "$LOG" 2>&1; rc=$?
    check "4b scale down to 2 mid-job: the 4 removed give their tiles back (said bye), same bytes" \
        "$([ $rc -eq 0 ] && [ "$d1" -lt 324 ] && [ $((before - left0)) -ge 1 ] && [ $((left1 - left0)) -ge 4 ] && same "$out" "$r"; echo $?)" \
        "status $rc, $((left1 - left0)) workers said bye, $((before - left0)) before the job ended; see $LOG"
}

# ---- 5: build ids ----------------------------------------------------------------
test5() {
    local a b c other log t0 t1
    t0=$(now)
    docker build -f docker/Dockerfile --build-arg GIT_ID="$GIT_ID" -t "tessera-$ID:again" . > "$WORK/build-again.log" 2>&1
    t1=$(now)
    a=$(docker run --rm "$IMAGE" --version); b=$(docker run --rm "tessera-$ID:again" --version)
    run_worker t5-same "tessera-$ID:again" --threads 1 > /dev/null
    local end=$((SECONDS + 30))
    c=0
    while [ $SECONDS -lt $end ] && [ "$c" -eq 0 ]; do
        c=$("$T" workers 2>> "$LOG" | awk '$1 == "t5-same"' | wc -l)
        sleep 0.2
    done
    echo "     $IMAGE says \"$a\"; built again ($(secs "$t0" "$t1") s): \"$b\""
    check "5a the same build twice: one build id, and its worker joins the pool" \
        "$([ -n "$a" ] && [ "$a" = "$b" ] && [ "$c" -eq 1 ]; echo $?)" "ids '$a' and '$b', joined $c"
    docker rm -f "$ID-t5-same" > /dev/null
    # Another build: the same sources, another GIT_ID (the Dockerfile stamps
    # the id after compiling, so this relinks rather than recompiles).
    t0=$(now)
    if ! docker build -f docker/Dockerfile --build-arg GIT_ID="${GIT_ID}-other" -t "tessera-$ID:other" . \
        > "$WORK/build-other.log" 2>&1; then
        fail "5b the other build failed: $(tail -3 "$WORK/build-other.log")"; return
    fi
    t1=$(now)
    other=$(docker run --rm "tessera-$ID:other" --version)
    run_worker t5-other "tessera-$ID:other" --threads 1 > /dev/null
    docker wait "$ID-t5-other" > "$WORK/t5-status" 2>&1
    log=$(docker logs "$ID-t5-other" 2>&1)
    local want="build 0.1.0+$GIT_ID-other; coordinator speaks protocol 1, build 0.1.0+$GIT_ID"
    echo "     another build ($(secs "$t0" "$t1") s): \"$other\"; refused with: $(echo "$log" | grep -m1 -o 'version mismatch.*')"
    check "5b a worker from another build is refused with both ids named (worker exit status $(cat "$WORK/t5-status"))" \
        "$([ "$(cat "$WORK/t5-status")" = 1 ] && grep -qF "$want" <<< "$log" &&
           grep -F "worker t5-other" <<< "$(clog)" | grep -F "$want" > /dev/null; echo $?)" "worker log: $log"
}

# ---- 7: tokens ---------------------------------------------------------------------
test7() {
    local job s1 s2 l1 l2 done0
    dc up -d --scale worker=0
    wait_workers 0 30
    job=$(submit 128 128 4 15)
    head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \n' > "$WORK/wrong"; chmod 0444 "$WORK/wrong"
    docker run -d --label "io.tessera.test=$ID" --name "$ID-t7-wrong" --network "$NET" --read-only \
        -v "$WORK/wrong:/run/secrets/tessera_token:ro" "$IMAGE" --connect coordinator:7000 --name t7-wrong \
        --token-file /run/secrets/tessera_token > /dev/null
    docker run -d --label "io.tessera.test=$ID" --name "$ID-t7-none" --network "$NET" --read-only \
        "$IMAGE" --connect coordinator:7000 --name t7-none --insecure > /dev/null  # tokenless on purpose: the coordinator must refuse it
    s1=$(docker wait "$ID-t7-wrong"); s2=$(docker wait "$ID-t7-none")
    l1=$(docker logs "$ID-t7-wrong" 2>&1); l2=$(docker logs "$ID-t7-none" 2>&1)
    done0=$(tiles_done "$job")
    local cl; cl=$("$T" status --token-file "$WORK/wrong" 2>&1); local cs=$?
    echo "     wrong token: \"$(echo "$l1" | tail -1)\"; coordinator: \"$(clog | grep -m1 'calling itself worker t7-wrong')\""
    check "7  wrong and missing token: workers refused (exit $s1, $s2), logged, nothing rendered; client refused" \
        "$(c=$(clog); [ "$s1" = 1 ] && [ "$s2" = 1 ] && grep -q "authentication failed" <<< "$l1" &&
           grep -q "authentication failed" <<< "$l2" &&
           grep -qF "calling itself worker t7-wrong): authentication failed (wrong token)" <<< "$c" &&
           grep -qF "calling itself worker t7-none): authentication failed (no token)" <<< "$c" &&
           [ "$done0" = 0 ] && [ $cs -ne 0 ] && grep -q "authentication failed" <<< "$cl"; echo $?)" \
        "exits $s1 $s2, tiles done $done0, client status $cs ($cl); logs: $l1 / $l2"
    "$T" cancel "$job" > /dev/null 2>> "$LOG"
}

# ---- 6: Swarm ------------------------------------------------------------------------
stack_coord() { docker ps -q --filter "label=com.docker.swarm.service.name=${STACK}_coordinator" | head -1; }
test6() {
    local state node r out=$WORK/t6.pfm pid rc busy
    # Leave the Compose pool out of it: its coordinator holds another port.
    dc down -v -t 3
    state=$(docker info -f '{{.Swarm.LocalNodeState}}')
    if [ "$state" != active ]; then
        docker network inspect docker_gwbridge > /dev/null 2>&1 || GWBRIDGE_MADE=1
        if ! docker swarm init --advertise-addr 127.0.0.1 >> "$LOG" 2>&1; then
            fail "6  docker swarm init: $(tail -2 "$LOG")"; return
        fi
        SWARM_MADE=1
    fi
    node=$(docker info -f '{{.Swarm.NodeID}}')
    if [ -z "$(docker node inspect -f '{{index .Spec.Labels "tessera.coordinator"}}' "$node")" ]; then
        docker node update --label-add tessera.coordinator=true "$node" >> "$LOG" 2>&1 && NODE_LABELLED=$node
    fi
    r=$(ref 384 384 4 16)
    STACK_UP=1
    if ! TESSERA_WORKERS=3 TESSERA_WORKER_THREADS=1 docker stack deploy --resolve-image never -c docker/stack.yaml -c tests/docker/stack.test.yaml "$STACK" >> "$LOG" 2>&1; then
        fail "6  docker stack deploy: $(tail -3 "$LOG")"; return
    fi
    if ! wait_workers 3 120; then
        fail "6  the stack's 3 workers never connected: $(docker service ls 2>&1 | grep "$STACK"; docker service ps --no-trunc "$STACK"_worker 2>&1 | head -5)"
        return
    fi
    "$T" submit "$SCENE" --width 384 --height 384 --spp 4 --seed 16 --wait -o "$out" >> "$LOG" 2>&1 &
    pid=$!
    sleep 1.5
    local t0 t1; t0=$(now)
    docker service scale --detach "${STACK}_worker=5" >> "$LOG" 2>&1
    local end=$((SECONDS + 60))
    while [ $SECONDS -lt $end ] && kill -0 "$pid" 2> /dev/null; do
        busy=$(worker_tiles | awk '$2 > 0' | wc -l)
        [ "$busy" -ge 5 ] && break
        sleep 0.2
    done
    t1=$(now)
    echo "     service scale to 5: $busy workers had done a tile $(secs "$t0" "$t1") s after the scale command"
    wait "$pid"; rc=$?
    check "6  Swarm stack, 3 worker replicas, scaled to 5 mid-job ($busy did tiles): same bytes" \
        "$([ $rc -eq 0 ] && same "$out" "$r" && [ "$busy" -ge 5 ]; echo $?)" "submit status $rc, $busy busy; see $LOG"
}

for t in $TESTS; do
    case $t in
    1|2|3|4|5|7) dc up -d --no-recreate coordinator || { fail "$t compose up: $(tail -3 "$LOG")"; continue; }; "test$t" ;;
    6) "test$t" ;;
    *) echo "no test $t" ;;
    esac
done
echo "$PASS passed, $FAIL failed"
[ "$FAIL" -eq 0 ]
