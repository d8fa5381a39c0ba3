#!/usr/bin/env bash
# CI test of the city-scale workflow (docs/city-scale.md) on a real, single-node Slurm cluster started here.
#
#   ci-test.sh ATLASTREE_BIN
#
# Needs root (the daemons; installs slurm-wlm and munge with apt-get when missing) and no systemd. Brings up
# munged (as the munge user, its own socket), slurmctld and slurmd (their own ports, config, state and logs) under
# one temp dir, so it touches neither /etc/slurm nor /run/munge nor a cluster already running here; then
#   0. checks the shape of tools/scaleout/k8s/build-job.yaml (when python3 has PyYAML);
#   1. builds data/city/scene.gltf in one process with FLAGS (a tree of depth ≥ 3: checked from the JSON report);
#   2. builds it as a 4-shard Slurm array + dependent merge with submit.sh --wait, and compares with cmp; then
#      again planned once (--plan: a plan job, the array after it, shards that read the plan) and compares;
#   3. builds it with the one-big-machine recipe (xargs, N = 3) and compares;
#   4. makes shard 2 of a 4-shard planned run fail: submit.sh --wait must exit non-zero naming shard 2, and the
#      merge must not run; then reruns just shard 2 (--only 2, reading the first run's plan) and compares;
#   5. kills (scancel) shard 1 of a 4-shard run submitted without --wait: submit.sh --attach must exit non-zero
#      naming shard 1 as killed (no exit status), and the merge must not run;
#   6. atlastree merge must refuse a shard set with one shard missing.
# Prints a PASS or FAIL line per check and exits non-zero if any failed. It always (trap) cancels its jobs, stops
# the daemons it started by the PIDs it read when they started, and removes its temp dir (CI_SLURM_KEEP=1 keeps
# the temp dir for debugging). Based on the bring-up tried in /work/shared/scaleout/slurm.md (Debian 12,
# Slurm 22.05, munge 0.5).
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
repo=$(cd "$here/../../.." && pwd)
prog=ci-test.sh
scene=$repo/data/city/scene.gltf
FLAGS=(--atlas-size 256 --leaf-originals 0)

say() { echo "==== $prog: $*"; }
failures=()
pass() { echo "PASS $*"; }
fail() {
    echo "FAIL $*"
    failures+=("$*")
}
fatal() {
    fail "$*"
    exit 1
}

(($# == 1)) || {
    echo "usage: $prog ATLASTREE_BIN" >&2
    exit 2
}
bin=$1
[[ -x $bin ]] || {
    echo "$prog: not an executable: $bin (build it first: cargo build --release)" >&2
    exit 2
}
bin=$(realpath "$bin")
[[ $(id -u) == 0 ]] || {
    echo "$prog: needs root (it starts munged, slurmctld and slurmd)" >&2
    exit 2
}
start_all=$SECONDS

if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v munged >/dev/null; then
    command -v apt-get >/dev/null || {
        echo "$prog: Slurm is not installed and there is no apt-get" >&2
        exit 2
    }
    say "installing slurm-wlm (and munge)"
    t=$SECONDS
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null
    say "apt-get install took $((SECONDS - t)) s"
fi
[[ -r /etc/munge/munge.key ]] || {
    echo "$prog: no /etc/munge/munge.key (the munge package creates it)" >&2
    exit 2
}

tmp=$(mktemp -d /tmp/atlastree-slurm-ci.XXXXXX)
chmod 0755 "$tmp" # the munge user must reach its directory inside
munge_pid="" ctld_pid="" slurmd_pid=""

stop_pids() { # NAME:PID…: SIGTERM them all, wait up to 10 s for all to exit, then SIGKILL what is left
    local np pid i live=()
    for np in "$@"; do
        pid=${np#*:}
        [[ -n $pid ]] && kill "$pid" 2>/dev/null && live+=("$np")
    done
    for ((i = 0; i < 100 && ${#live[@]}; i++)); do
        sleep 0.1
        local still=()
        for np in "${live[@]}"; do
            kill -0 "${np#*:}" 2>/dev/null && still+=("$np")
        done
        live=("${still[@]}")
    done
    for np in "${live[@]}"; do
        echo "$prog: ${np%%:*} (pid ${np#*:}) still running 10 s after SIGTERM; SIGKILL" >&2
        kill -9 "${np#*:}" 2>/dev/null || true
    done
    return 0
}

exec 8>&1 9>&2 # the script's own stdout and stderr, for cleanup: a signal can arrive inside a redirected command
cleanup() {
    local rc=$?
    set +e
    trap - EXIT INT TERM
    exec 1>&8 2>&9
    if [[ -n $ctld_pid ]] && kill -0 "$ctld_pid" 2>/dev/null; then
        local jobs i
        jobs=$(squeue -h -o %A 2>/dev/null | sort -u | tr '\n' ' ')
        if [[ -n ${jobs// /} ]]; then
            say "cancelling leftover jobs: $jobs"
            # shellcheck disable=SC2086 # a list of job ids
            scancel $jobs
            for ((i = 0; i < 100; i++)); do
                [[ -z $(squeue -h -o %A 2>/dev/null) ]] && break
                sleep 0.1
            done
        fi
    fi
    # PIDs were read when each daemon started: the daemons delete their PID files while exiting.
    [[ -n $slurmd_pid ]] || slurmd_pid=$(cat "$tmp/run/slurmd.pid" 2>/dev/null)
    [[ -n $ctld_pid ]] || ctld_pid=$(cat "$tmp/run/slurmctld.pid" 2>/dev/null)
    [[ -n $munge_pid ]] || munge_pid=$(cat "$tmp/munge/munged.pid" 2>/dev/null)
    stop_pids "slurmd:$slurmd_pid" "slurmctld:$ctld_pid"
    stop_pids "munged:$munge_pid" # last: slurmd and slurmctld authenticate through it while stopping
    if [[ ${CI_SLURM_KEEP:-0} == 1 ]]; then
        say "kept $tmp"
    else
        rm -rf -- "$tmp"
    fi
    say "daemons stopped, temp dir removed; total $((SECONDS - start_all)) s"
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

show_logs() {
    local f
    for f in "$tmp"/munge/munged.log "$tmp"/log/slurmctld.log "$tmp"/log/slurmd.log; do
        [[ -f $f ]] || continue
        echo "---- $f (last 15 lines)"
        tail -n 15 "$f"
    done
}

wait_pid_file() { # FILE: print the PID once the file holds one (10 s at most)
    local i pid
    for ((i = 0; i < 100; i++)); do
        pid=$(cat "$1" 2>/dev/null || true)
        if [[ $pid =~ ^[0-9]+$ ]]; then
            echo "$pid"
            return 0
        fi
        sleep 0.1
    done
    return 1
}

port_free() { # PORT: nothing listens on it and it can be bound (a real bind where python3 is here)
    (exec 3<>"/dev/tcp/127.0.0.1/$1") 2>/dev/null && return 1
    if command -v python3 >/dev/null; then
        python3 - "$1" <<'PY' 2>/dev/null
import socket, sys
s = socket.socket()
s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
s.bind(("0.0.0.0", int(sys.argv[1])))
PY
    fi
}

# Below the kernel's ephemeral range: a port in it can be taken at any moment by an outgoing connection, and
# slurmctld then dies with "Address already in use" (a CI run on 2026-12-03 lost 45 min that way).
ephemeral_low=$(awk '{print $1}' /proc/sys/net/ipv4/ip_local_port_range 2>/dev/null || echo 32768)
[[ $ephemeral_low =~ ^[0-9]+$ ]] && ((ephemeral_low > 12000)) || ephemeral_low=32768
free_port_pair() { # ATTEMPT: two consecutive free TCP ports in 10000..ephemeral_low-2, from a PID-dependent start
    local p i span=$(((ephemeral_low - 10002) / 2))
    for ((i = 0; i < 50; i++)); do
        p=$((10000 + (($$ * 7 + (i + 50 * $1) * 211) % span) * 2))
        if port_free "$p" && port_free $((p + 1)); then
            echo "$p"
            return 0
        fi
    done
    return 1
}

alive() { [[ -n $1 ]] && kill -0 "$1" 2>/dev/null; }

# ---- 0. the Kubernetes manifest (no cluster here: its shape only) ----
k8s_check=$repo/tools/scaleout/k8s/check.py
py=""
for p in python3 /usr/bin/python3; do
    if command -v "$p" >/dev/null && "$p" -c 'import yaml' 2>/dev/null; then
        py=$p
        break
    fi
done
if [[ -z $py ]]; then
    echo "SKIP k8s manifest: no python3 with PyYAML (apt-get install python3-yaml)"
elif k8s_out=$("$py" "$k8s_check" 2>&1); then
    pass "k8s manifest: $k8s_out"
else
    fail "k8s manifest: $k8s_out"
fi

# ---- bring-up ----
t=$SECONDS
host=$(hostname -s)
mkdir -p "$tmp"/{etc,run,log,state,spool,shared}
install -d -o munge -g munge -m 0755 "$tmp/munge" # munged: the socket dir must be searchable by all
munge_socket=$tmp/munge/munge.socket
runuser -u munge -- /usr/sbin/munged --socket="$munge_socket" --pid-file="$tmp/munge/munged.pid" \
    --log-file="$tmp/munge/munged.log" --seed-file="$tmp/munge/munged.seed" ||
    {
        show_logs
        fatal "cluster: munged did not start"
    }
munge_pid=$(wait_pid_file "$tmp/munge/munged.pid") || fatal "cluster: munged wrote no PID file"

node_line=$(slurmd -C | head -n1)
[[ $node_line == NodeName=* ]] || fatal "cluster: slurmd -C printed no node line: $node_line"
cpus=$(sed -n 's/.* CPUs=\([0-9]*\).*/\1/p' <<<"$node_line")
if [[ -n $cpus ]] && (($(nproc) < cpus)); then
    # A container limited below the hardware: offer Slurm only the CPUs we may use.
    node_line="NodeName=$host CPUs=$(nproc) $(grep -o 'RealMemory=[0-9]*' <<<"$node_line")"
fi
export SLURM_CONF=$tmp/etc/slurm.conf
write_conf() { # PORT: slurm.conf with slurmctld on PORT and slurmd on PORT+1
    # Loopback addresses: a single node, and no reliance on the container resolving its own host name.
    cat >"$SLURM_CONF" <<EOF
ClusterName=atlastree-ci
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$1
SlurmdPort=$(($1 + 1))
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$munge_socket
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MailProg=/bin/true
SchedulerParameters=batch_sched_delay=0
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/run/slurmctld.pid
SlurmdPidFile=$tmp/run/slurmd.pid
SlurmctldLogFile=$tmp/log/slurmctld.log
SlurmdLogFile=$tmp/log/slurmd.log
$node_line NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=ci Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
}

listening() { # PID PORT: wait (10 s at most) until PORT accepts connections; fail early if PID exits
    local i
    for ((i = 0; i < 100; i++)); do
        alive "$1" || return 1
        (exec 3<>"/dev/tcp/127.0.0.1/$2") 2>/dev/null && return 0
        sleep 0.1
    done
    return 1
}

# Up to 4 tries, each on a fresh port pair: a port that looked free can still be taken before the daemon binds it.
# Every wait below has a deadline and stops as soon as a daemon died (Slurm's clients retry a dead controller
# for ~10 s per call, so polling one for "idle" 300 times took 45 min).
port="" state=""
for ((attempt = 0; attempt < 4; attempt++)); do
    port=$(free_port_pair "$attempt") || fatal "cluster: found no two free TCP ports below $ephemeral_low"
    write_conf "$port"
    rm -f "$tmp"/run/*.pid
    slurmctld -i || {
        show_logs
        fatal "cluster: slurmctld did not start"
    }
    ctld_pid=$(wait_pid_file "$tmp/run/slurmctld.pid") || {
        show_logs
        fatal "cluster: slurmctld wrote no PID file"
    }
    if ! listening "$ctld_pid" "$port"; then
        show_logs
        echo "$prog: slurmctld (pid $ctld_pid) is not listening on port $port; stopping it, trying other ports" >&2
        stop_pids "slurmctld:$ctld_pid"
        ctld_pid=""
        continue
    fi
    slurmd || {
        show_logs
        fatal "cluster: slurmd did not start"
    }
    slurmd_pid=$(wait_pid_file "$tmp/run/slurmd.pid") || {
        show_logs
        fatal "cluster: slurmd wrote no PID file"
    }
    if ! listening "$slurmd_pid" $((port + 1)); then
        show_logs
        echo "$prog: slurmd (pid $slurmd_pid) is not listening on port $((port + 1)); stopping both, trying other ports" >&2
        stop_pids "slurmd:$slurmd_pid" "slurmctld:$ctld_pid"
        slurmd_pid="" ctld_pid=""
        continue
    fi
    t_idle=$SECONDS
    while ((SECONDS - t_idle < 30)) && alive "$ctld_pid" && alive "$slurmd_pid"; do
        state=$(timeout 5 sinfo -h -n "$host" -o %T 2>/dev/null || true)
        [[ $state == idle ]] && break
        sleep 0.1
    done
    [[ $state == idle ]] && break
    show_logs
    fatal "cluster: node $host is '${state:-not listed}' after $((SECONDS - t_idle)) s, not idle" \
        "(slurmctld $(alive "$ctld_pid" && echo running || echo dead), slurmd $(alive "$slurmd_pid" && echo running || echo dead))"
done
[[ $state == idle ]] || fatal "cluster: no try of 4 brought slurmctld and slurmd up (see the logs above)"
pass "cluster: munged $munge_pid, slurmctld $ctld_pid, slurmd $slurmd_pid on $host, ports $port/$((port + 1)), node idle after $((SECONDS - t)) s"

# ---- 1. one-process reference ----
timed() { # LABEL CMD…: run, print its time
    local label=$1 t=$SECONDS rc=0
    shift
    "$@" || rc=$?
    say "$label: exit $rc in $((SECONDS - t)) s" >&8 # the script's stdout, also when the command's is redirected
    return "$rc"
}
ref=$tmp/ref/city.atlastree
mkdir -p "$tmp/ref"
timed "one-process build" "$bin" build "$scene" -o "$ref" "${FLAGS[@]}" -q --json >"$tmp/ref/report.json" ||
    fatal "reference: atlastree build ${FLAGS[*]} failed"
depth=$(grep -o '"depth": *[0-9]*' "$tmp/ref/report.json" | grep -o '[0-9]*$' | sort -n | tail -n1)
if [[ -n $depth ]] && ((depth >= 3)); then
    pass "reference: one-process build, deepest tree depth $depth (≥ 3), $(stat -c %s "$ref") bytes"
else
    fatal "reference: deepest tree depth '${depth:-none}' in the JSON report, need ≥ 3 for a meaningful shard test"
fi

compare() { # LABEL FILE
    if [[ ! -f $2 ]]; then
        fail "$1: $2 was not written"
    elif cmp "$ref" "$2"; then
        pass "$1: cmp: merged file identical to the one-process build"
    else
        fail "$1: cmp: merged file differs from the one-process build"
    fi
}

export ATLASTREE_RC_GRACE=1 # a local disk: an rc file that is missing once the jobs left the queue stays missing

# ---- 2. Slurm array of 4 shards + dependent merge ----
out=$tmp/shared/slurm/city.atlastree
mkdir -p "$(dirname "$out")"
if timed "slurm 4 shards + merge" "$here/submit.sh" --wait --timeout 300 --poll 0.5 --bin "$bin" \
    "$scene" "$out" 4 "${FLAGS[@]}" -q; then
    compare "slurm array, 4 shards" "$out"
else
    fail "slurm array, 4 shards: submit.sh --wait failed"
fi
out=$tmp/shared/planned/city.atlastree
mkdir -p "$(dirname "$out")"
if timed "slurm plan + 4 shards + merge" "$here/submit.sh" --wait --plan --timeout 300 --poll 0.5 --bin "$bin" \
    "$scene" "$out" 4 "${FLAGS[@]}" -q >"$tmp/planned.txt" 2>&1; then
    sed 's/^/    | /' "$tmp/planned.txt"
    if grep -q '^ok   plan' "$tmp/planned.txt" && [[ -f $out.plan ]]; then
        compare "slurm plan job + array of 4 planned shards" "$out"
    else
        fail "planned run: submit.sh --wait --plan succeeded without a plan job or $(basename "$out").plan"
    fi
else
    sed 's/^/    | /' "$tmp/planned.txt"
    fail "planned run, 4 shards: submit.sh --wait --plan failed"
fi

# ---- 3. one big machine: xargs, N = 3 ----
out=$tmp/shared/xargs/city.atlastree
mkdir -p "$(dirname "$out")"
N=3 J=2
xargs_recipe() {
    seq 0 $((N - 1)) | xargs -P "$J" -I{} "$bin" build "$scene" -o "$out" "${FLAGS[@]}" -q --shard "{}/$N" &&
        "$bin" merge "$out"
}
if timed "xargs 3 shards + merge" xargs_recipe; then
    compare "xargs recipe, 3 shards" "$out"
else
    fail "xargs recipe, 3 shards: a build or the merge failed"
fi

# ---- 4. a failing shard is named, the merge does not run; rerunning just that shard mends it ----
out=$tmp/shared/fail/city.atlastree
mkdir -p "$(dirname "$out")"
failing=$tmp/faulty-atlastree
cat >"$failing" <<EOF
#!/usr/bin/env bash
# atlastree, except in the Slurm array task CI_SHARD_FAULT names: TASK:exit exits 3, TASK:hang sleeps (to be killed)
if [[ \${CI_SHARD_FAULT:-} == "\${SLURM_ARRAY_TASK_ID:-none}:exit" ]]; then
    echo "failing on purpose (ci-test)" >&2
    exit 3
elif [[ \${CI_SHARD_FAULT:-} == "\${SLURM_ARRAY_TASK_ID:-none}:hang" ]]; then
    echo "hanging on purpose (ci-test)" >&2
    exec sleep 600
fi
exec $(printf %q "$bin") "\$@"
EOF
chmod +x "$failing"
rc=0
CI_SHARD_FAULT=2:exit timed "slurm plan + 4 shards, shard 2 failing" "$here/submit.sh" --wait --plan --timeout 300 --poll 0.5 --bin "$failing" \
    "$scene" "$out" 4 "${FLAGS[@]}" -q >"$tmp/fail.txt" 2>&1 || rc=$?
sed 's/^/    | /' "$tmp/fail.txt"
if ((rc == 0)); then
    fail "failing shard: submit.sh --wait exited 0 although shard 2 exited 3"
elif ! grep -q '^FAIL shard 2 of 4: atlastree build exited 3' "$tmp/fail.txt"; then
    fail "failing shard: submit.sh --wait exited $rc without naming shard 2 and its exit status 3"
elif grep -q '^FAIL shard [013] ' "$tmp/fail.txt"; then
    fail "failing shard: submit.sh --wait blamed a shard that succeeded"
elif [[ -e $out ]]; then
    fail "failing shard: the merge ran although shard 2 failed ($out exists)"
else
    pass "failing shard: submit.sh --wait exited $rc naming shard 2 (exit 3); merge cancelled, no $(basename "$out")"
fi
if timed "slurm rerun of shard 2 + merge" "$here/submit.sh" --wait --timeout 300 --poll 0.5 --bin "$bin" --only 2 \
    "$scene" "$out" 4 "${FLAGS[@]}" -q; then
    compare "rerun of the failed shard (--only 2)" "$out"
else
    fail "rerun of the failed shard (--only 2): submit.sh --wait failed"
fi

# ---- 5. a killed shard (scancel; the same for a time limit or a lost node) is named, checked with --attach ----
out=$tmp/shared/killed/city.atlastree
mkdir -p "$(dirname "$out")"
t=$SECONDS
rc=0
CI_SHARD_FAULT=1:hang "$here/submit.sh" --bin "$failing" "$scene" "$out" 4 "${FLAGS[@]}" -q >"$tmp/killed.txt" 2>&1 ||
    rc=$?
info=$(sed -n 's/.*check later with: .* --attach //p' "$tmp/killed.txt")
aid=$(sed -n 's/^aid=//p' "$info" 2>/dev/null || true)
if ((rc != 0)) || [[ -z $aid ]]; then
    sed 's/^/    | /' "$tmp/killed.txt"
    fail "killed shard: submit.sh without --wait exited $rc or printed no run file"
else
    running=""
    for ((i = 0; i < 600; i++)); do
        running=$(squeue -h -r -o '%i %T' -j "$aid" 2>/dev/null | grep -x "${aid}_1 RUNNING" || true)
        [[ -n $running ]] && break
        sleep 0.1
    done
    [[ -n $running ]] && scancel "${aid}_1"
    rc=0
    "$here/submit.sh" --attach "$info" --timeout 120 --poll 0.5 >"$tmp/attach.txt" 2>&1 || rc=$?
    sed 's/^/    | /' "$tmp/attach.txt"
    say "slurm 4 shards, shard 1 killed: exit $rc in $((SECONDS - t)) s"
    if [[ -z $running ]]; then
        fail "killed shard: task ${aid}_1 never ran"
    elif ((rc == 0)); then
        fail "killed shard: submit.sh --attach exited 0 although shard 1 was killed"
    elif ! grep -q '^FAIL shard 1 of 4: no exit status' "$tmp/attach.txt"; then
        fail "killed shard: submit.sh --attach exited $rc without naming shard 1 as killed"
    elif grep -q '^FAIL shard [023] ' "$tmp/attach.txt" || [[ -e $out ]]; then
        fail "killed shard: another shard was blamed, or the merge ran"
    else
        pass "killed shard: submit.sh --attach exited $rc naming shard 1 (no exit status); merge cancelled"
    fi
fi

# ---- 6. merge refuses an incomplete shard set ----
out=$tmp/shared/xargs/city.atlastree
rm -f "$out" "$out.shard-1-of-3"
rc=0
"$bin" merge "$out" >"$tmp/merge-missing.txt" 2>&1 || rc=$?
if ((rc != 0)) && [[ ! -e $out ]]; then
    pass "merge with shard 1 of 3 missing: exit $rc: $(head -n1 "$tmp/merge-missing.txt")"
else
    fail "merge with shard 1 of 3 missing: exit $rc, $([[ -e $out ]] && echo "wrote $out" || echo "no output")"
fi

if ((${#failures[@]})); then
    say "FAILED ${#failures[@]} check(s):"
    printf '  %s\n' "${failures[@]}"
    exit 1
fi
say "all checks passed in $((SECONDS - start_all)) s"
