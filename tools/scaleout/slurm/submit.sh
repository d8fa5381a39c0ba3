#!/usr/bin/env bash
# Build an atlastree paging file on a Slurm cluster: N shards as one job array, then the merge as a job that
# depends on all of them. See docs/city-scale.md.
#
#   submit.sh [OPTIONS] SCENE OUT N [build flags…]
#   submit.sh --attach OUT.slurm/<array job id>.info      (wait for / check a run submitted earlier)
#
# What it submits
#   - an array job `--array=0-(N-1)` of build.sbatch: task I runs `atlastree build SCENE -o OUT --shard auto FLAGS`
#     (atlastree takes I and N from SLURM_ARRAY_TASK_ID / SLURM_ARRAY_TASK_COUNT) and writes OUT.shard-I-of-N;
#   - merge.sbatch with `--dependency=afterok:<array job> --kill-on-invalid-dep=yes`: `atlastree merge --shards N OUT`
#     runs once every shard succeeded, and is cancelled as soon as one fails;
#   - with --plan, first plan.sbatch (`atlastree build SCENE -o OUT --shard plan FLAGS`: the plan, once, into
#     OUT.plan), and the array depends on it (afterok): the shards read the plan and hold none of the scene's
#     triangles, so they need far less memory than the plan job (give it more with --plan-sbatch --mem=…).
#     Without --plan every shard plans the whole tree itself, and a full run removes an OUT.plan left behind.
#   Each task writes its exit status to STATE/<array job>.shard-<I>.rc, the merge to STATE/<array job>.merge.rc,
#   the plan to STATE/<plan job>.plan.rc;
#   sbatch logs go to STATE/<array job>.shard-<I>.log and STATE/<array job>.merge.log. STATE defaults to OUT.slurm.
#
# With --wait it polls `squeue` until both jobs have left the queue, then checks every rc file and the merge's,
# and exits 0 only when all hold 0 and OUT exists; otherwise it names each failed shard (with its exit status and
# the end of its log) and prints the command that reruns just those shards. It does not use `sbatch --wait`: that
# can exit 0 although a shard failed (a finished task's record is purged MinJobAge seconds after it ends, even
# while its siblings still run; a job cancelled before it ran also gives 0).
#
# Assumptions (a real cluster)
#   - SCENE (and its .bin and textures), the directory of OUT and STATE are on a filesystem shared by the submit
#     host and every compute node, at the same path (NFS, Lustre, GPFS, CephFS…). Shard files are written beside
#     OUT, so OUT's directory needs room for about twice the final file (the shards, then the merged copy).
#   - The atlastree binary (--bin, default $ATLASTREE_BIN, else `atlastree` from PATH) is at the same path on every
#     node, e.g. on the shared filesystem; it is resolved to an absolute path here.
#   - Jobs get the submitter's environment (sbatch's default --export=ALL) and run in STATE (--chdir).
#   - Site settings (partition, account, time limit, memory, CPUs per shard) come from --sbatch ARG (repeatable,
#     given to both sbatch calls) or from sbatch's own environment variables (SBATCH_PARTITION, SBATCH_ACCOUNT,
#     SBATCH_TIMELIMIT, …). A shard is one process using all CPUs it may run on: give it several, e.g.
#     --sbatch --cpus-per-task=8 --sbatch --mem=32G.
#   - N must not exceed the cluster's MaxArraySize (default 1001; `scontrol show config | grep MaxArraySize`).
#   - The submit host can run sbatch, squeue and (for --wait) read STATE.
#
# Options (before SCENE)
#   --wait              wait for the run and check it (see above); exit status 0 only on success
#   --bin PATH          the atlastree binary
#   --state DIR         directory for rc files and logs (default OUT.slurm; created)
#   --only LIST         rerun only these shards (comma-separated: 2,5) of an earlier run with the same N and flags,
#                       then merge; they run with `--shard I/N` (a sparse array cannot use --shard auto)
#   --max-parallel P    at most P shards run at once (--array=…%P)
#   --sbatch ARG        extra argument for every sbatch call (repeatable)
#   --plan              plan once in a job of its own before the shards (see above)
#   --plan-sbatch ARG   extra argument for the plan job's sbatch only (repeatable), e.g. --mem=64G
#   --poll S            seconds between squeue polls with --wait (default 2)
#   --timeout S         with --wait: stop waiting after S seconds, exit 124 (the jobs keep running)
#   -h, --help
# Environment: ATLASTREE_RC_GRACE (default 10): seconds to wait for an rc file that is not visible yet once the
# jobs have left the queue (a shared filesystem's attribute cache can lag).
#
# A full run first deletes OUT.shard-*-of-* files left by earlier runs, so the merge sees only this run's shards.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
prog=submit.sh

die() {
    echo "$prog: $*" >&2
    exit 2
}

usage() {
    sed -n '2,/^set -euo/{/^set -euo/d;s/^# \{0,1\}//;p}' "${BASH_SOURCE[0]}"
}

wait_mode=0 bin=${ATLASTREE_BIN:-} state="" only="" max_parallel="" poll=2 timeout="" attach="" plan=0
sbatch_extra=()
plan_extra=()
while (($#)); do
    case $1 in
    --wait) wait_mode=1 && shift ;;
    --bin) bin=${2:?--bin needs a path} && shift 2 ;;
    --state) state=${2:?--state needs a directory} && shift 2 ;;
    --only) only=${2:?--only needs a list} && shift 2 ;;
    --max-parallel) max_parallel=${2:?--max-parallel needs a number} && shift 2 ;;
    --sbatch) sbatch_extra+=("${2:?--sbatch needs an argument}") && shift 2 ;;
    --plan) plan=1 && shift ;;
    --plan-sbatch) plan_extra+=("${2:?--plan-sbatch needs an argument}") && shift 2 ;;
    --poll) poll=${2:?--poll needs seconds} && shift 2 ;;
    --timeout) timeout=${2:?--timeout needs seconds} && shift 2 ;;
    --attach) attach=${2:?--attach needs an .info file} && shift 2 ;;
    -h | --help) usage && exit 0 ;;
    --) shift && break ;;
    -*) die "unknown option $1 (options go before SCENE; build flags after N)" ;;
    *) break ;;
    esac
done
[[ $poll =~ ^[0-9]+([.][0-9]+)?$ ]] || die "--poll: not a number of seconds: $poll"
[[ -z $timeout || $timeout =~ ^[0-9]+$ ]] || die "--timeout: not a whole number of seconds: $timeout"
rc_grace=${ATLASTREE_RC_GRACE:-10}
[[ $rc_grace =~ ^[0-9]+$ ]] || die "ATLASTREE_RC_GRACE: not a whole number of seconds: $rc_grace"

# Wait until both jobs have left the queue. squeue lists only jobs that are pending, running, completing…;
# an id already purged makes it fail with "Invalid job id", which also means done. Any other squeue failure
# (slurmctld restarting, network) is retried, never taken for "done".
wait_for_jobs() {
    local ids="$1,$2${3:+,$3}" out last="" errors=0 start=$SECONDS
    local left="the jobs keep running (scancel ${ids//,/ } stops them; $prog --attach $info_file checks them later)"
    # shellcheck disable=SC2064 # expand now: the message is fixed
    trap "echo; echo \"$prog: stopped waiting; $left\" >&2; exit 130" INT TERM
    while :; do
        if out=$(squeue -h -r -o '%i %T' -j "$ids" 2>&1); then
            errors=0
            [[ -z $out ]] && break
            local summary
            summary=$(awk '{n[$2]++} END {for (s in n) printf "%s%d %s", (k++ ? ", " : ""), n[s], tolower(s)}' \
                <<<"$out")
            if [[ $summary != "$last" ]]; then
                echo "$prog: $(date +%T) ${3:+plan job $3, }shard tasks of job $1 and merge job $2: $summary"
                last=$summary
            fi
        elif [[ $out == *"Invalid job id"* ]]; then
            break
        else
            errors=$((errors + 1))
            echo "$prog: squeue failed ($errors): $out" >&2
            ((errors < 30)) || { echo "$prog: squeue keeps failing; giving up" >&2 && exit 1; }
        fi
        if [[ -n $timeout ]] && ((SECONDS - start >= timeout)); then
            echo "$prog: still queued or running after ${timeout} s; $left" >&2
            exit 124
        fi
        sleep "$poll"
    done
    trap - INT TERM
}

# Print the rc in FILE, waiting up to rc_grace seconds for it to appear; print nothing if it never does.
read_rc() {
    local file=$1 t=0
    while [[ ! -f $file ]] && ((t < rc_grace)); do
        ls "$(dirname "$file")" >/dev/null 2>&1 || true # refresh a shared filesystem's directory cache
        sleep 1
        t=$((t + 1))
    done
    [[ -f $file ]] && head -n1 "$file"
    return 0
}

log_tail() {
    [[ -f $1 ]] && tail -n "${2:-8}" "$1" | sed 's/^/    | /'
    return 0
}

# Check every rc file of a finished run; exit non-zero naming each failure.
check_run() {
    local aid=$1 mid=$2 n=$3 tasks=$4 out=$5 pid=${6:-} failed=() t rc log
    if [[ -n $pid ]]; then
        rc=$(read_rc "$state/$pid.plan.rc")
        log=$state/$pid.plan.log
        if [[ $rc != 0 ]]; then
            echo "FAIL plan (job $pid): ${rc:+atlastree build --shard plan exited $rc}${rc:-no exit status (killed," \
                "cancelled or never ran)}; the shards (job $aid) and the merge (job $mid) were cancelled; log: $log" >&2
            log_tail "$log" >&2
            exit 1
        fi
        echo "ok   plan"
    fi
    for t in ${tasks//,/ }; do
        rc=$(read_rc "$state/$aid.shard-$t.rc")
        log=$state/$aid.shard-$t.log
        if [[ -z $rc ]]; then
            echo "FAIL shard $t of $n: no exit status (the task was killed, cancelled or never ran: time limit," \
                "memory, node failure, scancel); log: $log" >&2
            log_tail "$log" >&2
            failed+=("$t")
        elif [[ $rc != 0 ]]; then
            echo "FAIL shard $t of $n: atlastree build exited $rc; log: $log" >&2
            log_tail "$log" >&2
            failed+=("$t")
        else
            echo "ok   shard $t of $n"
        fi
    done
    if ((${#failed[@]})); then
        local list
        list=$(
            IFS=,
            echo "${failed[*]}"
        )
        echo "$prog: FAILED: shard(s) $list of $n failed; the merge (job $mid) was cancelled, $out not written." >&2
        echo "$prog: after fixing the cause, rerun just those and merge:" >&2
        echo "  $rerun_opts --only $list $rerun_args" >&2
        exit 1
    fi
    rc=$(read_rc "$state/$aid.merge.rc")
    log=$state/$aid.merge.log
    if [[ -z $rc ]]; then
        echo "FAIL merge (job $mid): no exit status (killed, cancelled or never ran); log: $log" >&2
        log_tail "$log" >&2
        exit 1
    elif [[ $rc != 0 ]]; then
        echo "FAIL merge (job $mid): atlastree merge exited $rc; log: $log" >&2
        log_tail "$log" >&2
        exit 1
    fi
    [[ -f $out ]] || {
        echo "FAIL merge (job $mid) exited 0 but $out does not exist" >&2
        exit 1
    }
    echo "$prog: OK: all $n shards and the merge succeeded: $out (merge report: $log)"
    grep -E '^ *(merged|slowest)' "$log" 2>/dev/null | sed 's/^ */    /' || true
}

if [[ -n $attach ]]; then
    info_file=$attach
    [[ -f $info_file ]] || die "no such run file: $info_file"
    # shellcheck disable=SC1090
    pid=""
    source "$info_file" # aid mid pid n tasks out state rerun_opts rerun_args (written below with printf %q)
    wait_for_jobs "$aid" "$mid" "$pid"
    check_run "$aid" "$mid" "$n" "$tasks" "$out" "$pid"
    exit 0
fi

(($# >= 3)) || {
    usage >&2
    exit 2
}
scene=$1 out=$2 n=$3
shift 3
flags=("$@")
[[ $n =~ ^[1-9][0-9]*$ ]] || die "N must be a positive whole number, not '$n'"
# `build --shard I/N` takes N ≤ 4096: every task of a larger array would be refused.
((${#n} <= 5 && n <= 4096)) || die "N must be at most 4096 (what \`atlastree build --shard\` takes), not $n"
[[ -f $scene ]] || die "no such scene: $scene"
out_dir=$(dirname "$out")
[[ -d $out_dir ]] || die "the directory of OUT does not exist: $out_dir"
for f in "${flags[@]}"; do
    case $f in
    -o | --out | --out=* | --shard | --shard=*) die "build flag $f: submit.sh sets -o and --shard itself" ;;
    esac
done
[[ -n $max_parallel && ! $max_parallel =~ ^[1-9][0-9]*$ ]] && die "--max-parallel: not a positive number: $max_parallel"

if [[ -z $bin ]]; then
    bin=$(command -v atlastree) || die "no atlastree in PATH; give --bin or ATLASTREE_BIN"
fi
[[ -x $bin ]] || die "not an executable: $bin"
bin=$(realpath "$bin")
scene=$(realpath "$scene")
out=$(realpath "$out_dir")/$(basename "$out")
command -v sbatch >/dev/null || die "no sbatch in PATH (is this a Slurm submit host?)"
[[ -n $state ]] || state=$out.slurm
mkdir -p "$state"
state=$(realpath "$state")

if [[ -n $only ]]; then
    [[ $only =~ ^[0-9]+(,[0-9]+)*$ ]] || die "--only: not a comma-separated list of shard numbers: $only"
    # Decimal whatever the leading zeros (bash reads 08 as bad octal, 010 as 8), each shard once; the
    # array gets the normalised numbers, which Slurm reads as the same tasks.
    normal=()
    for t in ${only//,/ }; do
        t=${t#"${t%%[!0]*}"}
        t=${t:-0}
        ((${#t} <= 9 && t < n)) || die "--only: shard $t does not exist (0..$((n - 1)))"
        [[ " ${normal[*]} " == *" $t "* ]] || normal+=("$t")
    done
    only=$(IFS=,; echo "${normal[*]}")
    tasks=$only mode=explicit array=$only
else
    tasks=$(seq -s, 0 $((n - 1))) mode=auto array=0-$((n - 1))
    shopt -s nullglob
    stale=("$out".shard-*-of-*)
    # A plan of an earlier run (this one plans none), where there is one.
    ((plan)) || stale+=("$out".plan "$out".plan.json)
    shopt -u nullglob
    present=()
    for f in "${stale[@]}"; do [[ -e $f ]] && present+=("$f"); done
    stale=("${present[@]}")
    if ((${#stale[@]})); then
        echo "$prog: removing ${#stale[@]} file(s) of an earlier run: ${stale[*]}"
        rm -f -- "${stale[@]}"
    fi
fi
[[ -n $max_parallel ]] && array+=%$max_parallel

# The command that reruns failed shards: this one's options and arguments, with --only between them.
rerun_opts=$(printf '%q ' "$here/submit.sh" --wait --bin "$bin" --state "$state")
[[ -z $max_parallel ]] || rerun_opts+=$(printf -- '--max-parallel %q ' "$max_parallel")
for a in "${sbatch_extra[@]}"; do rerun_opts+=$(printf -- '--sbatch %q ' "$a"); done
rerun_opts=${rerun_opts% }
rerun_args=$(printf '%q ' "$scene" "$out" "$n" "${flags[@]}")
rerun_args=${rerun_args% }

name=$(basename "$out")
pid="" after=()
if ((plan)); then
    [[ -z $only ]] || die "--plan with --only: a rerun of some shards reads the plan of the first run (leave out --plan)"
    pid=$(sbatch --parsable --job-name="atlastree-plan:$name" --chdir="$state" --output="$state/%j.plan.log" \
        "${sbatch_extra[@]}" "${plan_extra[@]}" "$here/plan.sbatch" "$state" "$bin" "$scene" "$out" "${flags[@]}") ||
        die "submitting the plan job failed (sbatch's message above); nothing was submitted"
    pid=${pid%%;*}
    [[ $pid =~ ^[0-9]+$ ]] || die "sbatch did not return a job id: $pid"
    after=(--dependency="afterok:$pid" --kill-on-invalid-dep=yes)
fi
aid=$(sbatch --parsable --array="$array" --job-name="atlastree-shards:$name" --chdir="$state" "${after[@]}" \
    --output="$state/%A.shard-%a.log" "${sbatch_extra[@]}" \
    "$here/build.sbatch" "$state" "$bin" "$scene" "$out" "$n" "$mode" "${flags[@]}") || {
    [[ -z $pid ]] || scancel "$pid" || true
    die "submitting the shard array failed (sbatch's message above)${pid:+; the plan job $pid was cancelled}"
}
aid=${aid%%;*}
[[ $aid =~ ^[0-9]+$ ]] || die "sbatch did not return a job id: $aid"
mid=$(sbatch --parsable --dependency="afterok:$aid" --kill-on-invalid-dep=yes --job-name="atlastree-merge:$name" \
    --chdir="$state" --output="$state/$aid.merge.log" "${sbatch_extra[@]}" \
    "$here/merge.sbatch" "$state" "$aid" "$bin" "$out" "$n") || {
    echo "$prog: submitting the merge failed; cancelling the shards (job $aid)${pid:+ and the plan (job $pid)}" >&2
    scancel "$aid" $pid || true
    exit 1
}
mid=${mid%%;*}

info_file=$state/$aid.info
{
    printf 'aid=%q\nmid=%q\npid=%q\nn=%q\ntasks=%q\nout=%q\nstate=%q\n' "$aid" "$mid" "$pid" "$n" "$tasks" "$out" \
        "$state"
    printf 'rerun_opts=%q\nrerun_args=%q\n' "$rerun_opts" "$rerun_args"
} >"$info_file"
echo "$prog: submitted ${pid:+the plan as job $pid, }shards $array as array job $aid${pid:+ (afterok:$pid)}, merge as job $mid (afterok:$aid)"
echo "$prog: rc files and logs in $state/$aid.*; check later with: $here/submit.sh --attach $info_file"

((wait_mode)) || exit 0
wait_for_jobs "$aid" "$mid" "$pid"
check_run "$aid" "$mid" "$n" "$tasks" "$out" "$pid"
