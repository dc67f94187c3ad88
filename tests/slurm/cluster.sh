# cluster.sh - a private one-node Slurm cluster for tests, sourced by
# tests/slurm/run.sh: munged, slurmctld and slurmd with every file (config,
# key, state, spool, logs, pid files, munge socket) under $SLURM_DIR, their
# own ports, and nothing from /etc/slurm or /etc/munge. cluster_stop stops
# exactly the processes whose pids cluster_start recorded.
#
#   cluster_start DIR   set up and start; exports SLURM_CONF; returns non-zero
#                       (with the reason on stderr) if the node never comes up
#   cluster_stop        cancel our jobs, stop our daemons, idempotent

# Set by cluster_start.
SLURM_DIR=""
MUNGE_SOCKET="" # $SLURM_DIR/munge.socket, through a short link in /tmp when $SLURM_DIR is deep
CLUSTER_PIDS=()

# A TCP port on 127.0.0.1 nobody answers on right now (best effort).
cluster_free_port() {
    local p
    for _ in $(seq 1 100); do
        p=$((20000 + RANDOM % 40000))
        if ! (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; then echo "$p"; return 0; fi
    done
    return 1
}

# Kill the process whose pid is in file $1 if it is still the program $2
# (pid files from an earlier run may name a reused pid).
cluster_kill_pidfile() {
    local f=$1 prog=$2 pid
    [ -s "$f" ] || return 0
    pid=$(cat "$f")
    if [ -n "$pid" ] && [ "$(cat "/proc/$pid/comm" 2>/dev/null)" = "$prog" ]; then
        kill "$pid" 2>/dev/null
        for _ in $(seq 1 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
        kill -9 "$pid" 2>/dev/null || true
    fi
    rm -f "$f"
}

cluster_write_conf() {
    local d=$1 node ctld_port slurmd_port cpus
    node=$(hostname -s)
    cpus=$(nproc)
    ctld_port=$(cluster_free_port) && slurmd_port=$(cluster_free_port) || return 1
    cat >"$d/slurm.conf" <<EOF
# Written by tests/slurm/cluster.sh: a one-node test cluster, everything under $d.
ClusterName=tessera-test
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$MUNGE_SOCKET
StateSaveLocation=$d/state
SlurmdSpoolDir=$d/spool
SlurmctldPidFile=$d/slurmctld.pid
SlurmdPidFile=$d/slurmd.pid
SlurmctldLogFile=$d/slurmctld.log
SlurmdLogFile=$d/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
PlugStackConfig=$d/plugstack.conf
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
SwitchType=switch/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
KillWait=5
MinJobAge=30
InactiveLimit=0
SlurmdTimeout=60
MessageTimeout=10
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=test Nodes=$node Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO
EOF
    : >"$d/plugstack.conf"
}

cluster_start() {
    SLURM_DIR=$(realpath -m "$1")
    cluster_stop_daemons # leftovers of an interrupted run in the same folder
    rm -rf "$SLURM_DIR"
    mkdir -p "$SLURM_DIR/state" "$SLURM_DIR/spool" "$SLURM_DIR/munge"
    chmod 700 "$SLURM_DIR" "$SLURM_DIR/munge"
    # munged and slurmstepd make unix sockets in here (at most 108 bytes a
    # path): name a deep build folder through a short link in /tmp.
    local d=$SLURM_DIR
    if [ ${#d} -gt 50 ]; then
        d=$(mktemp -u /tmp/tessera-slurm.XXXXXX) && ln -s "$SLURM_DIR" "$d" || return 1
        echo "$d" >"$SLURM_DIR/short-link"
    fi
    MUNGE_SOCKET=$d/munge.socket
    cluster_write_conf "$d" || { echo "cluster: no free port" >&2; return 1; }
    export SLURM_CONF="$d/slurm.conf"
    # munge: our own key, socket, pid, log and seed.
    dd if=/dev/urandom of="$d/munge/munge.key" bs=1024 count=1 status=none && chmod 400 "$d/munge/munge.key"
    munged --force --socket="$MUNGE_SOCKET" --key-file="$d/munge/munge.key" --pid-file="$d/munged.pid" \
        --log-file="$d/munged.log" --seed-file="$d/munge/munged.seed" || {
        echo "cluster: munged did not start; see $d/munged.log" >&2; return 1; }
    CLUSTER_PIDS+=("$d/munged.pid:munged")
    slurmctld -f "$SLURM_CONF" -i || { echo "cluster: slurmctld did not start; see $d/slurmctld.log" >&2; return 1; }
    CLUSTER_PIDS+=("$d/slurmctld.pid:slurmctld")
    slurmd -f "$SLURM_CONF" || { echo "cluster: slurmd did not start; see $d/slurmd.log" >&2; return 1; }
    CLUSTER_PIDS+=("$d/slurmd.pid:slurmd")
    local state="" end=$((SECONDS + 30))
    while [ "$SECONDS" -lt "$end" ]; do
        state=$(sinfo -h -N -o %T 2>/dev/null | head -1)
        [ "$state" = "idle" ] && return 0
        sleep 0.1
    done
    echo "cluster: the node is \"$state\", not idle, after 30 s; see $d/slurmctld.log and $d/slurmd.log" >&2
    return 1
}

# Stop the daemons recorded by pid file in $SLURM_DIR (slurmd first, so no
# step outlives it unnoticed; munged last).
cluster_stop_daemons() {
    [ -n "$SLURM_DIR" ] || return 0
    cluster_kill_pidfile "$SLURM_DIR/slurmd.pid" slurmd
    cluster_kill_pidfile "$SLURM_DIR/slurmctld.pid" slurmctld
    cluster_kill_pidfile "$SLURM_DIR/munged.pid" munged
    if [ -s "$SLURM_DIR/short-link" ]; then
        local link; link=$(cat "$SLURM_DIR/short-link")
        [ -L "$link" ] && rm -f "$link"
        rm -f "$SLURM_DIR/short-link"
    fi
}

cluster_stop() {
    [ -n "$SLURM_DIR" ] || return 0
    if [ -s "$SLURM_DIR/slurmctld.pid" ]; then
        scancel --full --quiet --user=root 2>/dev/null || true
        local end=$((SECONDS + 10))
        while [ "$SECONDS" -lt "$end" ]; do
            [ -z "$(squeue -h -o %i 2>/dev/null)" ] && break
            sleep 0.1
        done
    fi
    cluster_stop_daemons
    CLUSTER_PIDS=()
}
