#!/usr/bin/env bash
# Real scenes with the defaults: for each scene made by ../shared/realdata/make-scenes.sh, build it with
# `atlastree build` (no flags), then report file size, tree depth and node count (`inspect`), build time and
# peak RSS, `inspect --verify`, and nodes drawn per frame along the default camera path (`simulate`,
# capacity `all` and 40, 50 MB/s, 0 ms latency).
#
#   tools/real_tracks.sh SCENES_DIR OUT_DIR [NAME ...]     (default: every scene in SCENES_DIR)
set -euo pipefail
scenes=$1 out=$2
shift 2
bin=${ATLASTREE:-target/release/atlastree}
names=("$@")
[[ ${#names[@]} -gt 0 ]] || mapfile -t names < <(ls "$scenes")
mkdir -p "$out"
for s in "${names[@]}"; do
    file=$out/$s.atlastree
    /usr/bin/time -f "%e %M" -o "$out/$s.time" "$bin" build "$scenes/$s/scene.gltf" -o "$file" >/dev/null 2>&1
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
done
