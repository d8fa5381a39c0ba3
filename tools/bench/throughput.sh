#!/usr/bin/env bash
# Build throughput against decoding (issue 26), before/after: for each scene, the time `scene-info --decode`
# reports for decoding every used image once (all cores), then for each binary the build's wall time, build ÷
# decode, its `time:` stages and peak RSS, and whether its paging file is byte-identical to the first
# binary's. Prints a Markdown table.
#
#   tools/bench/throughput.sh "before=/tmp/old-atlastree after=target/release/atlastree" SCENE.gltf...
#
# FLAGS (default `--compress bc1`) are passed to every build; outputs go to a temporary folder.
set -euo pipefail
if [[ $# -lt 2 ]]; then
    echo "usage: tools/bench/throughput.sh \"LABEL=BIN [LABEL=BIN ...]\" SCENE.gltf...   (FLAGS=... for the builds)" >&2
    exit 2
fi
bins=$1
shift
flags=${FLAGS:---compress bc1}
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
echo "| scene | binary | decode s | build s | build ÷ decode | stages (s) | peak RSS MiB | same bytes |"
echo "|---|---|---|---|---|---|---|---|"
for scene in "$@"; do
    first=""
    for lb in $bins; do
        label=${lb%%=*} bin=${lb#*=}
        decode=$("$bin" scene-info --decode "$scene" 2>&1 | sed -n 's/^decoded .* in \([0-9.]*\) s on.*/\1/p')
        # shellcheck disable=SC2086 # FLAGS is a list of flags
        if ! /usr/bin/time -f "%e %M" -o "$out/time" "$bin" build "$scene" -o "$out/$label.atlastree" $flags \
            >"$out/log" 2>&1; then
            echo "throughput.sh: $label failed to build $scene:" >&2
            tail -5 "$out/log" >&2
            exit 1
        fi
        read -r secs kb <"$out/time"
        stages=$(sed -n 's/^ *time: //p' "$out/log" | sed 's/, total.*//' | tr '\n' ' ')
        same="—"
        if [[ -z $first ]]; then
            first=$out/$label.atlastree
        else
            cmp -s "$first" "$out/$label.atlastree" && same=yes || same=NO
        fi
        ratio=$(python3 -c "print(f'{$secs / $decode:.1f}×' if $decode > 0 else '—')")
        echo "| $(basename "$(dirname "$scene")") | $label | $decode | $secs | $ratio | $stages | $((kb / 1024)) | $same |"
    done
    rm -f "$out"/*.atlastree
done
