#!/bin/bash
# A one-node Slurm cluster on this machine, for testing the sweep scripts (docs/cluster.md).
#   scripts/local-slurm.sh up     # install if missing, configure, start munged, slurmctld, slurmd
#   scripts/local-slurm.sh down   # stop them and remove the state
# Run as root. The cluster's files live in $VIZSIM_SLURM_DIR (default /tmp/vizsim-slurm);
# its configuration is $VIZSIM_SLURM_DIR/slurm.conf, so clients need
#   export SLURM_CONF=$VIZSIM_SLURM_DIR/slurm.conf
# Exit codes: 0 done, 1 failed, 77 Slurm or munge cannot be installed or started here
# (the caller may skip on 77).
set -euo pipefail
DIR=${VIZSIM_SLURM_DIR:-/tmp/vizsim-slurm}
CONF=$DIR/slurm.conf
export SLURM_CONF=$CONF
CANNOT=77

say() { echo "local-slurm: $*" >&2; }
cannot() { say "cannot run Slurm here: $*"; exit "$CANNOT"; }

install_missing() {
    local missing=()
    command -v slurmctld >/dev/null || missing+=(slurmctld)
    command -v slurmd >/dev/null || missing+=(slurmd)
    command -v sbatch >/dev/null || missing+=(slurm-client)
    command -v munged >/dev/null || missing+=(munge)
    [ ${#missing[@]} -eq 0 ] && return 0
    [ "$(id -u)" -eq 0 ] || cannot "${missing[*]} missing and not root (apt-get needs root)"
    command -v apt-get >/dev/null || cannot "${missing[*]} missing and no apt-get"
    say "installing ${missing[*]} with apt-get"
    export DEBIAN_FRONTEND=noninteractive
    if ! { apt-get -y -q install --no-install-recommends "${missing[@]}" >"$DIR/apt.log" 2>&1 ||
        { apt-get -q update >>"$DIR/apt.log" 2>&1 &&
            apt-get -y -q install --no-install-recommends "${missing[@]}" >>"$DIR/apt.log" 2>&1; }; }; then
        tail -n 5 "$DIR/apt.log" >&2
        cannot "apt-get could not install ${missing[*]} (log: $DIR/apt.log)"
    fi
    for c in slurmctld slurmd sbatch munged; do
        command -v "$c" >/dev/null || cannot "$c is still missing after apt-get install ${missing[*]}"
    done
}

pid_of() { [ -s "$DIR/$1.pid" ] && cat "$DIR/$1.pid" || true; }

stop_one() { # name: kills the process whose id the name's pid file holds
    local pid
    pid=$(pid_of "$1")
    [ -n "$pid" ] || return 0
    if kill "$pid" 2>/dev/null; then
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
        kill -9 "$pid" 2>/dev/null || true
    fi
    rm -f "$DIR/$1.pid"
}

down() {
    [ -d "$DIR" ] || { say "nothing to stop ($DIR absent)"; return 0; }
    if [ -s "$CONF" ] && command -v scancel >/dev/null && [ -n "$(pid_of slurmctld)" ]; then
        timeout 10 scancel --full --quiet --user=root 2>/dev/null || true
    fi
    stop_one slurmd
    stop_one slurmctld
    stop_one munged
    rm -rf "$DIR"
    say "stopped; removed $DIR"
}

up() {
    [ "$(id -u)" -eq 0 ] || cannot "not root"
    if [ -n "$(pid_of slurmctld)" ]; then down; fi
    mkdir -p "$DIR"
    install_missing
    mkdir -p "$DIR/state" "$DIR/spool" "$DIR/log"

    # munge: a key (the package makes one; make one if it did not), and the daemon as user munge
    local key=/etc/munge/munge.key
    if [ ! -s "$key" ]; then
        mkdir -p /etc/munge
        dd if=/dev/urandom of="$key" bs=1024 count=1 status=none
        chown munge:munge "$key" 2>/dev/null || true
        chmod 0400 "$key"
    fi
    mkdir -p /run/munge /var/lib/munge /var/log/munge
    chown munge:munge /run/munge /var/lib/munge /var/log/munge 2>/dev/null || true
    chmod 0755 /run/munge
    if ! munge -n </dev/null 2>/dev/null | unmunge >/dev/null 2>&1; then
        rm -f /run/munge/munged.pid
        if id munge >/dev/null 2>&1; then
            runuser -u munge -- munged || cannot "munged did not start (log: /var/log/munge/munged.log)"
        else
            munged --force || cannot "munged did not start (log: /var/log/munge/munged.log)"
        fi
        for _ in $(seq 50); do [ -s /run/munge/munged.pid ] && break; sleep 0.1; done
        cp /run/munge/munged.pid "$DIR/munged.pid" 2>/dev/null || true
        munge -n </dev/null | unmunge >/dev/null || cannot "munge does not work (log: $DIR/log/munged.log)"
    fi

    # slurm.conf: this machine as the controller and the one node of partition "ci"
    local host node
    host=$(hostname -s)
    node=$(slurmd -C | head -n 1) || cannot "slurmd -C failed"
    case $node in NodeName=*) ;; *) cannot "slurmd -C printed no NodeName: $node" ;; esac
    cat >"$CONF" <<EOF
# written by scripts/local-slurm.sh: a one-node cluster for tests
ClusterName=vizsim-ci
SlurmctldHost=$host(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
ReturnToService=2
StateSaveLocation=$DIR/state
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/slurmctld.pid
SlurmdPidFile=$DIR/slurmd.pid
SlurmctldLogFile=$DIR/log/slurmctld.log
SlurmdLogFile=$DIR/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
MinJobAge=600
SchedulerType=sched/backfill
$node NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=ci Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF

    slurmctld -c -f "$CONF" || cannot "slurmctld did not start (log: $DIR/log/slurmctld.log)"
    slurmd -f "$CONF" || cannot "slurmd did not start (log: $DIR/log/slurmd.log)"
    local state=""
    for _ in $(seq 300); do
        state=$(sinfo -h -N -o '%T' 2>/dev/null | head -n 1 || true)
        [ "$state" = idle ] && break
        sleep 0.1
    done
    if [ "$state" != idle ]; then
        tail -n 5 "$DIR/log/slurmctld.log" "$DIR/log/slurmd.log" >&2 || true
        cannot "the node did not become idle within 30 s (state: ${state:-none})"
    fi
    say "up: $(sinfo -h -o '%P %D node(s) %c CPUs %T' | head -n 1); export SLURM_CONF=$CONF"
}

case ${1:-} in
up) up ;;
down) down ;;
*) echo "usage: $0 up|down" >&2; exit 1 ;;
esac
