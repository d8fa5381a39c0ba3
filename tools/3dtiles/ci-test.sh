#!/usr/bin/env bash
# End-to-end check of `atlastree export 3dtiles` in two real 3D Tiles clients (headless Chromium).
#   tools/3dtiles/ci-test.sh [ATLASTREE_BIN] [PAGING_FILE] [CAMS_JSON]
# or env ATLASTREE, PAGING, CAMS; also WORK (output dir, default a fresh /tmp/harness-ci.*),
# MIN_PSNR (default 0 = report only), VIEWERS (default 3dtr,cesium), WIDTH/HEIGHT (800x600).
# Steps: install what is missing (chromium from apt, npm ci), export, validate, three
# `atlastree render --selection` runs (overview/mid/street from the tileset's bounds, or CAMS_JSON),
# check.mjs with both viewers. Exit non-zero if validation or the check fails.
set -uo pipefail
HERE=$(cd "$(dirname "$0")" && pwd)
BIN=${1:-${ATLASTREE:-$HERE/../../target/release/atlastree}}
PAGING=${2:-${PAGING:-}}
CAMS=${3:-${CAMS:-}}
WORK=${WORK:-$(mktemp -d /tmp/harness-ci.XXXXXX)}
W=${WIDTH:-800} H=${HEIGHT:-600}
[ -x "$BIN" ] && [ -f "$PAGING" ] || { echo "usage: $0 ATLASTREE_BIN PAGING_FILE [CAMS_JSON]" >&2; exit 2; }

child=
# check.mjs closes its browser and server itself on SIGINT/SIGTERM; forward them to it
trap '[ -n "$child" ] && kill -TERM "$child" 2>/dev/null; exit 130' INT TERM
run() { "$@" & child=$!; wait "$child"; local rc=$?; child=; return $rc; }
step() { echo; echo "== $* ($(date +%T))"; }
t0=$(date +%s)

step setup
if ! command -v chromium >/dev/null; then
  apt-get install -y --no-install-recommends chromium || { apt-get update && apt-get install -y --no-install-recommends chromium; } || exit 1
fi
# npm ci when node_modules is missing or older than the lock file
if [ ! -f "$HERE/node_modules/.package-lock.json" ] || [ "$HERE/package-lock.json" -nt "$HERE/node_modules/.package-lock.json" ]; then
  (cd "$HERE" && npm ci --no-audit --no-fund) || exit 1
fi
chromium --version 2>/dev/null; echo "node $(node --version); work dir $WORK"

step export
run "$BIN" export 3dtiles "$PAGING" -o "$WORK/tiles" --force -q || exit 1

step validate
run node "$HERE/validate.mjs" "$WORK/tiles" --json "$WORK/validate.json"; valid=$?

step cameras
if [ -n "$CAMS" ]; then run node "$HERE/cameras.mjs" --from "$CAMS" --out "$WORK/cams" --width "$W" --height "$H"
else run node "$HERE/cameras.mjs" --tileset "$WORK/tiles" --out "$WORK/cams" --width "$W" --height "$H"; fi || exit 1

step "atlastree render --selection"
for p in "$WORK"/cams/*.path.json; do
  name=$(basename "$p" .path.json)
  size=$(node -e "const c=require('$WORK/cams/cams.json').find(c=>c.name==='$name'); console.log(c.width+' '+c.height)")
  read -r cw ch <<<"$size"
  run "$BIN" render "$PAGING" --path "$p" --frames 1 --every 1 --warmup 0 --width "$cw" --height "$ch" \
    --mode original --selection --out "$WORK/cams/sel-$name" > "$WORK/cams/render-$name.log" 2>&1 \
    || { echo "render $name failed:"; tail -5 "$WORK/cams/render-$name.log"; exit 1; }
  echo "$name: $(grep -c '"node"' "$WORK/cams/sel-$name/selection.json") nodes selected"
done

step "check in the viewers"
run node "$HERE/check.mjs" --tileset "$WORK/tiles" --cameras "$WORK/cams/cams.json" --out "$WORK/check" \
  --viewers "${VIEWERS:-3dtr,cesium}" --min-psnr "${MIN_PSNR:-0}"; checked=$?

echo; echo "validate: $([ $valid = 0 ] && echo ok || echo FAILED); check: $([ $checked = 0 ] && echo ok || echo FAILED); $(( $(date +%s) - t0 )) s; outputs in $WORK"
[ $valid = 0 ] && [ $checked = 0 ]
