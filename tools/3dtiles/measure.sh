#!/usr/bin/env bash
# The numbers of docs/3dtiles.md for one paging file: ci-test.sh (export, validate, both viewers at three
# cameras), the naive export beside it, atlastree's tree frames at the same cameras, then measure.mjs.
#   tools/3dtiles/measure.sh ATLASTREE_BIN PAGING_FILE WORK [CAMS_JSON]
set -uo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
BIN=$1 PAGING=$2 WORK=$3 CAMS=${4:-}
rm -rf "$WORK"
WORK=$WORK "$HERE/ci-test.sh" "$BIN" "$PAGING" $CAMS | tail -14 || echo "ci-test FAILED (measuring anyway)"
/usr/bin/time -f "naive export %e s, peak %M KB" "$BIN" export 3dtiles "$PAGING" -o "$WORK/naive" --naive --force -q | tail -3
for p in "$WORK"/cams/*.path.json; do
  name=$(basename "$p" .path.json)
  "$BIN" render "$PAGING" --path "$p" --frames 1 --every 1 --warmup 0 --mode tree --out "$WORK/cams/tree-$name" >/dev/null 2>&1 ||
    echo "render --mode tree $name failed"
done
node "$HERE/measure.mjs" --work "$WORK" --naive "$WORK/naive" --json "$WORK/measure.json"
