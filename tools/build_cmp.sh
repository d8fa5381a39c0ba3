#!/bin/sh
# Before/after builds (issue 17): file size, build time and the `originals:` lines per scene and binary.
#   tools/build_cmp.sh "v3=/tmp/v3_atlastree v4=/tmp/v4_atlastree now=target/release/atlastree" SCENE.gltf...
# Each build uses `--compress bc1` and otherwise the defaults; outputs go to a temporary folder.
set -eu
BINS=$1; shift
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT
for s in "$@"; do
  for lb in $BINS; do
    label=${lb%%=*}; bin=${lb#*=}
    start=$(date +%s.%N)
    "$bin" build "$s" --compress bc1 -o "$OUT/f.atlastree" > "$OUT/log" 2>&1
    end=$(date +%s.%N)
    size=$(stat -c %s "$OUT/f.atlastree")
    orig=$(grep 'originals:' "$OUT/log" | sed 's/.*images), //' | tr '\n' ' ' || true)
    python3 -c "print(f'$s $label {$size/1e6:.2f} MB {$end-$start:.2f} s $orig')"
  done
done
