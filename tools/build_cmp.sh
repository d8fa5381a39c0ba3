#!/bin/sh
# Before/after builds (issue 17): file size, build time and the `originals:` lines per scene and binary.
#   tools/build_cmp.sh "v3=/tmp/v3_atlastree v4=/tmp/v4_atlastree now=target/release/atlastree" SCENE.gltf...
# Each build uses `--compress bc1` and otherwise the defaults; outputs go to a temporary folder.
set -eu
if [ $# -lt 2 ]; then
  echo 'usage: tools/build_cmp.sh "LABEL=BIN [LABEL=BIN ...]" SCENE.gltf...' >&2
  exit 2
fi
BINS=$1; shift
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
for s in "$@"; do
  for lb in $BINS; do
    label=${lb%%=*}; bin=${lb#*=}
    start=$(date +%s.%N)
    if ! "$bin" build "$s" --compress bc1 -o "$OUT/f.atlastree" > "$OUT/log" 2>&1; then
      echo "build_cmp.sh: $label failed to build $s:" >&2
      tail -5 "$OUT/log" >&2
      exit 1
    fi
    end=$(date +%s.%N)
    size=$(stat -c %s "$OUT/f.atlastree")
    orig=$(grep 'originals:' "$OUT/log" | sed 's/.*images), //' | tr '\n' ' ' || true)
    # The scene's path as an argument, not pasted into the program (an apostrophe broke it).
    python3 -c 'import sys; s, l, size, t0, t1, o = sys.argv[1:]; print(f"{s} {l} {int(size) / 1e6:.2f} MB {float(t1) - float(t0):.2f} s {o}")' \
      "$s" "$label" "$size" "$start" "$end" "$orig"
  done
done
