// Shared by view-3dtr.html and view-cesium.html (ES module, served from tools/3dtiles).
// The page is opened as  view-*.html?cfg=<JSON>  with
//   { tileset: URL, camera: { eye, target, up, fov (horizontal, deg), near, far, width, height },
//     stableFrames: N, timeoutMs }
// camera in the scene's y-up frame. When done the page sets window.__harness.result =
//   { ok, tiles: [{tree, node, source, uri, via, conflict?}], frames, ms, notes: [...] }.
export const BACKGROUND_SRGB = [149, 180, 218];
export const cfg = JSON.parse(new URLSearchParams(location.search).get('cfg'));
window.__harness = { result: null };
const t0 = performance.now();

// `t{T}/n{N}.gltf` = atlas, `t{T}/n{N}-orig.gltf` = original (same regex as lib.mjs)
const URI_RE = /(?:^|\/)t(\d+)\/n(\d+)(-orig)?\.(?:gltf|glb)(?:[?#].*)?$/;
export function identify(uri, extras) {
  const m = URI_RE.exec(uri || '');
  const fromUri = m ? { tree: +m[1], node: +m[2], source: m[3] ? 'original' : 'atlas' } : null;
  const a = extras && extras.atlastree;
  const fromExtras = a ? { tree: a.tree, node: a.node, source: a.source } : null;
  const id = fromExtras || fromUri || { tree: null, node: null, source: null };
  const out = { ...id, uri: uri || null, via: fromExtras ? 'extras' : fromUri ? 'uri' : 'none' };
  if (fromUri && fromExtras && (fromUri.tree !== a.tree || fromUri.node !== a.node || fromUri.source !== a.source))
    out.conflict = `URI says ${JSON.stringify(fromUri)}, extras say ${JSON.stringify(fromExtras)}`;
  return out;
}

// Stable when the caller says nothing is loading and the visible set (a sorted signature) has not
// changed for cfg.stableFrames frames in a row.
export function stabilityTracker() {
  let last = null, stable = 0, frames = 0;
  return (busy, sig) => {
    frames++;
    stable = !busy && sig === last ? stable + 1 : 0;
    last = sig;
    return { frames, stable: stable >= (cfg.stableFrames ?? 5) };
  };
}

export function finish(tiles, frames, notes = [], ok = true) {
  tiles.sort((a, b) => (a.tree - b.tree) || (a.node - b.node) || String(a.source).localeCompare(b.source));
  window.__harness.result = { ok, tiles, frames, ms: Math.round(performance.now() - t0), notes };
}
