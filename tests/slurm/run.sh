#!/usr/bin/env bash
# run.sh - Tessera against a real Slurm (`make slurm-test`; docs/slurm.md).
#
#   tests/slurm/run.sh [BIN_DIR]               the checks; ends "N passed, N failed"
#   tests/slurm/run.sh BIN_DIR --bench-layout N   one worker per node vs per task, N rounds
#
# Needs root: installs slurm-wlm and munge when missing, then starts a private
# one-node cluster under build/slurm/ (tests/slurm/cluster.sh) and stops
# exactly its processes on exit, whatever happened. Prints one
# "slurm-test: skipped (...)" line and exits 0 when it cannot run here.
# All traffic stays on loopback.
set -uo pipefail
cd "$(dirname "$0")/../.."
ROOT=$PWD
BIN=$(realpath -m "${1:-build/release/bin}")
MODE=${2:-test}
ROUNDS=${3:-3}
SCENE=$ROOT/tests/scenes/cornell-small.json
SBATCH_RENDER=$ROOT/docker/slurm/tessera.sbatch
SBATCH_POOL=$ROOT/docker/slurm/pool.sbatch

skip() { echo "slurm-test: skipped ($*)"; exit 0; }
[ "$(id -u)" -eq 0 ] || skip "needs root to start slurmctld, slurmd and munged"
[ -x "$BIN/tessera" ] && [ -x "$BIN/tessera-worker" ] || { echo "slurm-test: no tessera binaries in $BIN (run make)" >&2; exit 1; }
if ! command -v sbatch >/dev/null || ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null ||
   ! command -v munged >/dev/null; then
    echo "slurm-test: installing slurm-wlm and munge"
    { apt-get -o DPkg::Lock::Timeout=900 update -qq &&
      DEBIAN_FRONTEND=noninteractive apt-get install -y -qq -o DPkg::Lock::Timeout=900 slurm-wlm munge; } >/dev/null ||
        skip "apt-get could not install slurm-wlm and munge"
fi

# shellcheck source=tests/slurm/cluster.sh
source "$ROOT/tests/slurm/cluster.sh"
BG_PIDS=() # our own background processes (coordinators, workers, srun), stopped on exit
cleanup() {
    local p
    for p in "${BG_PIDS[@]}"; do kill "$p" 2>/dev/null; done
    cluster_stop
}
trap cleanup EXIT
trap 'exit 130' INT TERM
cluster_start "$ROOT/build/slurm" || { echo "slurm-test: could not start the test cluster" >&2; exit 1; }
WORK=$SLURM_DIR/work
mkdir -p "$WORK"
cd "$WORK" || exit 1 # the submit directory: images and job logs land here
export TESSERA_BIN=$BIN
# Workers dial the batch host by name; keep it on loopback here.
case $(getent hosts "$(hostname -f 2>/dev/null || hostname)" | awk '{print $1; exit}') in
127.*|::1) ;;
*) export TESSERA_HOST=127.0.0.1 TESSERA_LISTEN=127.0.0.1 ;;
esac

PASSED=0 FAILED=0 CUR_FAILS=0
fail() { echo "    $*"; CUR_FAILS=$((CUR_FAILS + 1)); }
begin() { CUR=$1; CUR_FAILS=0; T0=$(date +%s.%N); }
finish() {
    local s; s=$(awk -v a="$T0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.2f", b - a }')
    if [ "$CUR_FAILS" -eq 0 ]; then echo "ok   $CUR (${s}s)"; PASSED=$((PASSED + 1));
    else echo "FAIL $CUR (${s}s)"; FAILED=$((FAILED + 1)); fi
}
now() { date +%s.%N; }
sub() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.2f", a - b }'; }

# Wait until job $1 is no longer in squeue (up to $2 s); GONE_AT = when it
# left. (Not in a $(...) subshell, so a signal reaches the trap at once.)
GONE_AT=""
wait_gone() {
    local j=$1 end=$((SECONDS + ${2:-120}))
    GONE_AT=""
    while [ "$SECONDS" -lt "$end" ]; do
        if [ -z "$(squeue -h -j "$j" -o %i 2>/dev/null)" ]; then GONE_AT=$(now); return 0; fi
        sleep 0.05
    done
    return 1
}
# The exit code ("0:0") Slurm recorded for job $1.
job_exit() { scontrol show job "$1" 2>/dev/null | sed -n 's/.* ExitCode=\([0-9:]*\).*/\1/p' | head -1; }
# Wait up to $3 s for file $1 to contain $2.
wait_text() {
    local end=$((SECONDS + $3))
    while [ "$SECONDS" -lt "$end" ]; do grep -q -- "$2" "$1" 2>/dev/null && return 0; sleep 0.05; done
    return 1
}
# The number after "$2" on a "tessera.sbatch: ..." line of log $1.
stamp() { sed -n "s/^tessera.sbatch: $2 \([0-9.]*\).*/\1/p" "$1" | head -1; }

"$BIN/tessera" render "$SCENE" --workers 0 -o ref.pfm --no-progress >ref.log 2>&1 ||
    { echo "slurm-test: the reference render failed: $(cat ref.log)"; exit 1; }

if [ "$MODE" = "--bench-layout" ]; then
    # Same job, two layouts, rounds interleaved: the render's own seconds.
    echo "layout bench: cornell-box 512x512 16 spp on $(nproc) CPUs, sbatch -n $(nproc), $ROUNDS rounds"
    for r in $(seq 1 "$ROUNDS"); do
        for layout in node task; do
            j=$(TESSERA_LAYOUT=$layout sbatch --parsable -n "$(nproc)" "$SBATCH_RENDER" "$ROOT/scenes/cornell-box.json" \
                --width 512 --height 512 --spp 16 -o "bench-$layout.pfm")
            wait_gone "$j" 300
            secs=$(sed -n 's/^rendered .*: \([0-9.]*\) s, \([0-9.]*\) Msamples.*/\1 s \2 Msamples\/s/p' "tessera-$j.log")
            echo "round $r layout $layout: $secs ($(job_exit "$j"))"
        done
    done
    cmp -s bench-node.pfm bench-task.pfm && echo "images identical" || echo "IMAGES DIFFER"
    exit 0
fi

# ---- an sbatch render equals the single-process render; the allocation goes at once
begin sbatch_render_identical
t_submit=$(now)
j=$(sbatch --parsable -n 2 "$SBATCH_RENDER" "$SCENE" -o sbatch.pfm)
wait_gone "$j" 120 || fail "job $j still queued after 120 s"
t_gone=$GONE_AT
log=tessera-$j.log
[ "$(job_exit "$j")" = "0:0" ] || fail "job $j exit code $(job_exit "$j"), want 0:0; log $WORK/$log"
cmp -s sbatch.pfm ref.pfm || fail "sbatch.pfm differs from the single-process render; log $WORK/$log"
t_end=$(stamp "$log" "render ended at")
t_srun=$(stamp "$log" "srun started at")
joined=$(sed -n 's/^tessera.sbatch: first worker joined \([0-9.]*\) s after srun/\1/p' "$log")
if [ -n "$t_end" ] && [ -n "$t_gone" ]; then
    release=$(sub "$t_gone" "$t_end")
    awk -v r="$release" 'BEGIN { exit !(r < 8) }' || fail "allocation released $release s after the render, want < 8"
    grep -q "(--idle-exit 3); leaving" "$log" || fail "workers did not leave by --idle-exit; log $WORK/$log"
    echo "    figures: submit to srun $(sub "$t_srun" "$t_submit") s, srun to first worker joined ${joined:-?} s," \
         "render end to allocation released $release s"
else
    fail "no render end stamp in $WORK/$log"
fi
finish

# ---- the job's exit status is the render's
begin sbatch_exit_status_is_the_renders
j=$(sbatch --parsable -n 1 "$SBATCH_RENDER" "$WORK/no-such-scene.json" -o never.pfm)
wait_gone "$j" 60 || fail "job $j still queued after 60 s"
[ "$(job_exit "$j")" = "1:0" ] || fail "job $j exit code $(job_exit "$j"), want 1:0 (tessera's); log $WORK/tessera-$j.log"
grep -q "no-such-scene.json" "tessera-$j.log" || fail "the log does not name the missing scene; $WORK/tessera-$j.log"
[ ! -e never.pfm ] || fail "an image was written for a failed render"
finish

# ---- scancel of one worker step mid-render: the same bytes
begin scancel_worker_step_same_image
j=$(TESSERA_LAYOUT=task TESSERA_WORKER_ARGS="--throttle-ms 40" sbatch --parsable -n 2 "$SBATCH_RENDER" "$SCENE" \
    --tile-size 8 -o scancel.pfm)
log=tessera-$j.log
if wait_text "$log" "coordinator at " 60; then
    addr=$(sed -n 's/^tessera.sbatch: coordinator at \([^;]*\);.*/\1/p' "$log")
    # A second worker step in the same job, holding tiles when it is cancelled.
    srun --jobid="$j" --overlap -n 1 --job-name=extra "$BIN/tessera-worker" --connect "$addr" --threads 1 \
        --name extra --throttle-ms 40 --token-file "/tmp/tessera-token-$j" --idle-exit 3 >extra.log 2>&1 &
    extra=$!
    BG_PIDS+=("$extra")
    wait_text "$log" "worker extra (" 60 || fail "the extra step's worker never joined; logs $WORK/$log $WORK/extra.log"
    sleep 0.5
    step=$(squeue -h -s -j "$j" -o "%i %j" | awk '$2 == "extra" { print $1 }')
    [ -n "$step" ] && scancel "$step" || fail "no step named extra to cancel"
    wait "$extra"
    wait_gone "$j" 120 || fail "job $j still queued after 120 s"
    [ "$(job_exit "$j")" = "0:0" ] || fail "job $j exit code $(job_exit "$j"); log $WORK/$log"
    cmp -s scancel.pfm ref.pfm || fail "scancel.pfm differs from the single-process render; log $WORK/$log"
    grep -q "worker extra (.*its unfinished tiles go back to the queue" "$log" ||
        fail "the coordinator did not take the cancelled step's tiles back; log $WORK/$log"
    # scancel of a step kills its tasks outright (SIGKILL): the tiles come
    # back through the lost connection, as after kill -9.
    echo "    extra step $step: $(grep -h -o "task 0: .*" extra.log | head -1); coordinator: $(grep -o "worker extra (.*left: .*" "$log" | head -1 | sed 's/.*left: //')"
else
    fail "the coordinator never started; log $WORK/$log"
fi
finish

# ---- a worker pool (sbatch --array) joins a running job service and leaves when idle
begin pool_array_joins_service_and_leaves
port=$(cluster_free_port)
(umask 077; head -c 32 /dev/urandom | od -An -tx1 | tr -d ' \n' >token)
rm -rf svc
"$BIN/tessera-coordinator" --listen "127.0.0.1:$port" --data-dir svc --token-file token -v >svc.log 2>&1 &
svc=$!
BG_PIDS+=("$svc")
wait_text svc.log "listening on" 30 || fail "the job service did not start; log $WORK/svc.log"
a=$(TESSERA_TOKEN_FILE=$WORK/token TESSERA_IDLE_EXIT=3 sbatch --parsable --array=1-2 -c 1 "$SBATCH_POOL" "127.0.0.1:$port")
export TESSERA_COORDINATOR=127.0.0.1:$port TESSERA_TOKEN_FILE=$WORK/token
timeout 120 "$BIN/tessera" submit "$SCENE" --wait -o pool.pfm >submit.log 2>&1 ||
    fail "tessera submit --wait failed: $(tail -3 submit.log)"
t_done=$(now)
"$BIN/tessera" workers >workers.txt 2>&1
unset TESSERA_COORDINATOR TESSERA_TOKEN_FILE
cmp -s pool.pfm ref.pfm || fail "pool.pfm differs from the single-process render"
for t in 1 2; do
    grep -q "slurm-${a}-$t" workers.txt || fail "array task $t is not among the service's workers: $(cat workers.txt)"
done
wait_gone "$a" 60 || fail "pool $a still queued 60 s after the job"
t_gone=$GONE_AT
for t in 1 2; do
    f=tessera-pool-${a}_$t.log
    grep -q "no work from the coordinator at 127.0.0.1:$port for .* (--idle-exit 3); leaving" "$f" ||
        fail "array task $t did not leave by --idle-exit; log $WORK/$f"
    [ "$(job_exit "${a}_$t")" = "0:0" ] || fail "array task $t exit code $(job_exit "${a}_$t")"
done
[ -n "$t_gone" ] && echo "    pool left $(sub "$t_gone" "$t_done") s after the job was done (--idle-exit 3)"
kill -TERM "$svc"
wait "$svc" || fail "the job service did not stop cleanly; log $WORK/svc.log"
finish

# ---- Slurm's time limit: SIGTERM, and the worker gives its tiles back
begin time_limit_sigterm_gives_tiles_back
port=$(cluster_free_port)
"$BIN/tessera" render "$SCENE" --tile-size 8 --no-progress -v -o timelimit.pfm --listen "127.0.0.1:$port" \
    >timelimit-coord.log 2>&1 &
coord=$!
BG_PIDS+=("$coord")
wait_text timelimit-coord.log "coordinator listening on" 30 || fail "coordinator did not start"
# One slow worker (2 s a tile, 64 tiles) under a 1-minute limit: still busy when the limit hits.
j=$(TESSERA_WORKER_ARGS="--threads 1 --throttle-ms 2000" sbatch --parsable --time=1 -c 1 "$SBATCH_POOL" "127.0.0.1:$port")
wait_text timelimit-coord.log "worker slurm-$j-0 (" 60 || fail "the worker under the time limit never joined"
wait_gone "$j" 150 || fail "job $j still running 150 s after its 1-minute limit"
grep -q "SIGTERM: abandoning [1-9][0-9]* tiles*" tessera-pool-"$j"*.log ||
    fail "the worker did not get SIGTERM while holding tiles; log $WORK/$(ls tessera-pool-"$j"*.log 2>/dev/null)"
grep -q "worker slurm-$j-0 (.*left: worker left (.*its unfinished tiles go back to the queue" timelimit-coord.log ||
    fail "the coordinator did not get the tiles back; log $WORK/timelimit-coord.log"
scontrol show job "$j" | grep -q "JobState=TIMEOUT" || fail "job $j did not end by its time limit: $(scontrol show job "$j" | grep -o "JobState=[A-Z_]*")"
echo "    $(grep -h -o "SIGTERM: abandoning .*" tessera-pool-"$j"*.log | head -1); coordinator: $(grep -o "worker slurm-$j-0 (.*left: .*" timelimit-coord.log | head -1 | sed 's/.*left: //')"
# Another worker finishes the render: the same bytes.
"$BIN/tessera-worker" --connect "127.0.0.1:$port" --threads 2 --idle-exit 2 >timelimit-w.log 2>&1 &
finisher=$!
BG_PIDS+=("$finisher")
wait "$coord" || fail "the coordinator failed; log $WORK/timelimit-coord.log"
wait "$finisher" || fail "the finishing worker did not exit 0; log $WORK/timelimit-w.log"
cmp -s timelimit.pfm ref.pfm || fail "timelimit.pfm differs from the single-process render"
finish

echo "$PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
