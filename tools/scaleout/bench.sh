#!/usr/bin/env bash
# Sharded-build benchmark (issue 22): the one-process build of SCENE, then the same build as N shards run one
# after another on this machine and the merge, each under /usr/bin/time (wall seconds, peak RSS); checks the
# merged file is byte-identical and prints a Markdown table plus the critical path on N machines
# (max shard + merge) against the one-process time. With PLAN=1 the plan is made once first (`--shard plan`),
# the shards read it, and the critical path adds the plan step. ONE=0 skips the one-process build (its file must
# then be WORKDIR/one.atlastree already, with ONE_S its seconds).
#
#   tools/scaleout/bench.sh BIN SCENE WORKDIR N [build flags…]
#   e.g. tools/scaleout/bench.sh target/release/atlastree /tmp/berlin4/scene.gltf /tmp/bench 4 --compress bc1
set -euo pipefail
if [[ $# -lt 4 ]]; then
    echo "usage: tools/scaleout/bench.sh BIN SCENE WORKDIR N [build flags…]   (PLAN=1, ONE=0 ONE_S=…)" >&2
    exit 2
fi
bin=$1 scene=$2 work=$3 n=$4
shift 4
mkdir -p "$work"
one="$work/one.atlastree" out="$work/sharded.atlastree"
plan=${PLAN:-0}
[[ ${ONE:-1} == 0 ]] || rm -f "$one"
rm -f "$out" "$out".shard-* "$out".plan "$out".plan.json

# Runs a command under GNU time; prints "seconds peak_kib". A failed command's exit status is returned
# (its time file removed either way).
timed() {
    local log rc=0
    log=$(mktemp)
    /usr/bin/time -f '%e %M' -o "$log" "$@" >/dev/null || rc=$?
    ((rc)) || cat "$log"
    rm -f "$log"
    return "$rc"
}

if [[ ${ONE:-1} == 0 ]]; then
    one_s=${ONE_S:?ONE=0 needs ONE_S, the one-process seconds} one_kib=0
else
    read -r one_s one_kib < <(timed "$bin" build "$scene" -o "$one" -q "$@")
fi
echo "| step | wall s | peak RSS MiB |"
echo "|---|---|---|"
echo "| one process | $one_s | $((one_kib / 1024)) |"
plan_s=0
if [[ $plan == 1 ]]; then
    read -r plan_s plan_kib < <(timed "$bin" build "$scene" -o "$out" -q "$@" --shard plan)
    echo "| plan | $plan_s | $((plan_kib / 1024)) |"
fi
max_s=0 sum_s=0 max_kib=0
for ((i = 0; i < n; i++)); do
    read -r s kib < <(timed "$bin" build "$scene" -o "$out" -q "$@" --shard "$i/$n")
    echo "| shard $i/$n | $s | $((kib / 1024)) |"
    max_s=$(python3 -c "print(max($max_s, $s))")
    sum_s=$(python3 -c "print($sum_s + $s)")
    ((kib > max_kib)) && max_kib=$kib
done
read -r merge_s merge_kib < <(timed "$bin" merge "$out" -q)
echo "| merge | $merge_s | $((merge_kib / 1024)) |"
if cmp -s "$one" "$out"; then ident="byte-identical"; else ident="DIFFERENT"; fi
python3 - "$one_s" "$max_s" "$sum_s" "$merge_s" "$n" "$ident" "$plan_s" <<'PY'
import sys
one, mx, total, merge, n, ident, plan = float(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5]), sys.argv[6], float(sys.argv[7])
mean = total / n
first = f"plan {plan:.1f} + " if plan > 0 else ""
label = "plan + max shard + merge" if plan > 0 else "max shard + merge"
print(f"\nmerged file: {ident}; critical path on {n} machines = {label} = {first}{mx:.1f} + {merge:.1f} s = "
      f"{(plan + mx + merge) / one:.2f}× the one-process {one:.1f} s; merge {merge / one:.1%} of it; max/mean shard {mx / mean:.2f}; "
      f"plan and shards together {(plan + total) / one:.2f}× the one-process CPU time")
PY
[[ $ident == byte-identical ]]
