#!/usr/bin/env bash
# Real scenes with the defaults: for each scene made by ../shared/realdata/make-scenes.sh, build it with
# `atlastree build` (no flags), then report file size, tree depth and node count (`inspect`), build time and
# peak RSS, `inspect --verify`, and nodes drawn per frame along the default camera path (`simulate`,
# capacity `all` and 40, 50 MB/s, 0 ms latency).
#
#   tools/real_tracks.sh SCENES_DIR OUT_DIR [NAME ...]     (default: every scene in SCENES_DIR)
set -euo pipefail
if [[ $# -lt 2 ]]; then
    echo "usage: tools/real_tracks.sh SCENES_DIR OUT_DIR [NAME ...]   (ATLASTREE=BIN for another binary)" >&2
    exit 2
fi
scenes=$1 out=$2
shift 2
bin=${ATLASTREE:-target/release/atlastree}
names=("$@")
# The scene folders only (a README beside them is not a scene).
[[ ${#names[@]} -gt 0 ]] || mapfile -t names < <(cd "$scenes" && for d in */; do [[ -f $d/scene.gltf ]] && echo "${d%/}"; done)
mkdir -p "$out"
failed=0
for s in "${names[@]}"; do
    file=$out/$s.atlastree
    if ! /usr/bin/time -f "%e %M" -o "$out/$s.time" "$bin" build "$scenes/$s/scene.gltf" -o "$file" \
        >"$out/$s.log" 2>&1; then
        echo "$s: build FAILED ($out/$s.log):" >&2
        tail -3 "$out/$s.log" >&2
        failed=$((failed + 1))
        continue
    fi
    rm -f "$out/$s.log"
    read -r secs kb <"$out/$s.time"
    info=$("$bin" inspect "$file")
    depth=$(grep -oE 'depth [0-9]+' <<<"$info" | awk '{print $2}' | sort -n | tail -1)
    nodes=$(grep -oE 'tree: [0-9]+ nodes' <<<"$info" | awk '{s += $2} END {print s}')
    verify=$("$bin" inspect --verify "$file" >/dev/null 2>&1 && echo ok || echo FAILED)
    echo "$s: $(( $(stat -c %s "$file") / 1048576 )) MiB, depth $depth, $nodes nodes, build ${secs} s, peak RSS $((kb / 1024)) MiB, verify $verify"
    for k in all 40; do
        rm -rf "$out/sim"
        "$bin" simulate "$file" --capacity "$k" --bandwidth 50MB/s --latency 0ms --out "$out/sim" >/dev/null
        python3 - "$out/sim/frames.csv" "$s" "$k" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
drawn = [int(r["drawn_items"]) for r in rows]
coarser = [float(r["coarser_share"]) for r in rows]
print(f"  {sys.argv[2]} k={sys.argv[3]}: {len(rows)} frames, nodes drawn per frame mean {sum(drawn) / len(drawn):.1f} "
      f"max {max(drawn)}, mean coarser share {sum(coarser) / len(coarser):.3f}")
PY
    done
    rm -rf "$out/sim" "$out/$s.time"
done
if [[ $failed -gt 0 ]]; then
    echo "real_tracks.sh: $failed build(s) failed" >&2
    exit 1
fi
