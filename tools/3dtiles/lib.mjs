// Shared helpers for check.mjs, validate.mjs and measure.mjs: tile identity, tileset walking, camera geometry, PNG and PSNR.
// Frames: the scene (and every camera) is y-up; the 3D Tiles tile frame is z-up.
// A y-up point (x, y, z) is the tile-frame point (x, -z, y); glTF content is y-up and the clients
// rotate it +90° about x into the tile frame (the same map).
import fs from 'node:fs';
import path from 'node:path';
import pngjs from 'pngjs';

export const BACKGROUND_SRGB = [149, 180, 218];

// ---- tile identity -------------------------------------------------------------------------------

// `t{T}/n{N}.gltf` = atlas, `t{T}/n{N}-orig.gltf` = original (the contract); .glb accepted too.
const URI_RE = /(?:^|\/)t(\d+)\/n(\d+)(-orig)?\.(?:gltf|glb)(?:[?#].*)?$/;
export function parseContentUri(uri) {
  const m = URI_RE.exec(uri || '');
  return m ? { tree: +m[1], node: +m[2], source: m[3] ? 'original' : 'atlas' } : null;
}
export const itemKey = (it) => `${it.tree}/${it.node}/${it.source}`;
// atlastree-export.json's per-tile list: `tile_list` (what the exporter writes; `tiles` is a count)
export const exportTiles = (e) => (Array.isArray(e.tile_list) ? e.tile_list : Array.isArray(e.tiles) ? e.tiles : []);

// ---- small vector / matrix helpers (4x4 matrices are column-major, as in 3D Tiles and glTF) -------

export const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
export const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
export const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
export const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
export const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
export const norm = (a) => scale(a, 1 / Math.hypot(...a));
export const yUpToZUp = ([x, y, z]) => [x, -z, y];

export const IDENTITY = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1];
export function mul(a, b) {
  const r = new Array(16).fill(0);
  for (let c = 0; c < 4; c++)
    for (let row = 0; row < 4; row++)
      for (let k = 0; k < 4; k++) r[c * 4 + row] += a[k * 4 + row] * b[c * 4 + k];
  return r;
}
export const apply = (m, p) => [0, 1, 2].map((i) => m[i] * p[0] + m[4 + i] * p[1] + m[8 + i] * p[2] + m[12 + i]);
// glTF node TRS -> matrix
export function trs(n) {
  if (n.matrix) return n.matrix;
  const [tx, ty, tz] = n.translation || [0, 0, 0];
  const [x, y, z, w] = n.rotation || [0, 0, 0, 1];
  const [sx, sy, sz] = n.scale || [1, 1, 1];
  return [
    (1 - 2 * (y * y + z * z)) * sx, 2 * (x * y + z * w) * sx, 2 * (x * z - y * w) * sx, 0,
    2 * (x * y - z * w) * sy, (1 - 2 * (x * x + z * z)) * sy, 2 * (y * z + x * w) * sy, 0,
    2 * (x * z + y * w) * sz, 2 * (y * z - x * w) * sz, (1 - 2 * (x * x + y * y)) * sz, 0,
    tx, ty, tz, 1,
  ];
}
export const corners = (min, max) =>
  [0, 1, 2, 3, 4, 5, 6, 7].map((i) => [i & 1 ? max[0] : min[0], i & 2 ? max[1] : min[1], i & 4 ? max[2] : min[2]]);

// ---- tileset walking (node side) -------------------------------------------------------------------

// Loads DIR/tileset.json and any external tilesets it references. Returns
// { tilesets: [{file, json}], tiles: [...] }; each tile: { id, parent (id|null), file (tileset json),
// uri (content URI resolved relative to DIR, posix, or null), geometricError, refine (effective),
// world (transform to the root frame, including its own), box (12 numbers, in the tile's own frame,
// or null), extras, ident ({tree,node,source} from the URI, or null) }.
// Tiles whose content is an external tileset are kept (uri ends in .json); the external root is
// their child.
export function loadTileset(dir, { onError = (m) => { throw new Error(m); } } = {}) {
  const tilesets = [];
  const tiles = [];
  function walkFile(rel, parentId, parentWorld, parentRefine) {
    const file = path.join(dir, rel);
    let json;
    try { json = JSON.parse(fs.readFileSync(file, 'utf8')); } catch (e) { onError(`${rel}: ${e.message}`); return; }
    tilesets.push({ file: rel, json });
    walkTile(json.root, rel, parentId, parentWorld, parentRefine);
  }
  function walkTile(t, rel, parentId, parentWorld, parentRefine) {
    const world = t.transform ? mul(parentWorld, t.transform) : parentWorld;
    const c = t.content || (t.contents && t.contents[0]);
    const rawUri = c && (c.uri ?? c.url);
    const uri = rawUri != null ? path.posix.normalize(path.posix.join(path.posix.dirname(rel), decodeURI(rawUri))) : null;
    const rec = {
      id: tiles.length, parent: parentId, file: rel, uri, geometricError: t.geometricError,
      refine: t.refine || parentRefine, ownRefine: t.refine, world, box: t.boundingVolume?.box ?? null,
      boundingVolume: t.boundingVolume, extras: t.extras, ident: uri ? parseContentUri(uri) : null, children: [],
    };
    tiles.push(rec);
    if (parentId != null) tiles[parentId].children.push(rec.id);
    for (const ch of t.children || []) walkTile(ch, rel, rec.id, world, rec.refine);
    if (uri && uri.endsWith('.json')) walkFile(uri, rec.id, world, rec.refine);
  }
  walkFile('tileset.json', null, IDENTITY, undefined);
  return { tilesets, tiles };
}

// Is point p (root frame) inside the tile's box (in the frame `world`)? Relative tolerance tol
// per half-axis, plus an absolute floor for degenerate (flat) axes.
export function insideBox(p, box, world, tol = 1e-3) {
  const c = apply(world, box.slice(0, 3));
  const o = apply(world, [0, 0, 0]);
  const d = sub(p, c);
  let maxHalf = 0;
  const axes = [3, 6, 9].map((i) => sub(apply(world, box.slice(i, i + 3)), o));
  for (const a of axes) maxHalf = Math.max(maxHalf, Math.hypot(...a));
  for (const a of axes) {
    const len2 = dot(a, a);
    const excess = Math.abs(dot(d, a)) / Math.sqrt(len2 || 1) - Math.sqrt(len2);
    if (excess > tol * maxHalf + 1e-9) return false;
  }
  return true;
}

// ---- camera geometry (scene y-up frame) --------------------------------------------------------------

// cam: { eye, target, up, fov (horizontal, degrees), near, far, width, height }
export function cameraBasis(cam) {
  const f = norm(sub(cam.target, cam.eye));
  const r = norm(cross(f, cam.up));
  const u = cross(r, f);
  const tanX = Math.tan((cam.fov * Math.PI) / 360);
  const tanY = (tanX * cam.height) / cam.width;
  return { f, r, u, tanX, tanY };
}
export const fovYDeg = (cam) => (2 * Math.atan(cameraBasis(cam).tanY) * 180) / Math.PI;

// Distance from point e to the AABB [min, max] (0 inside): what atlastree and both viewers measure.
export function aabbDistance(e, min, max) {
  let s = 0;
  for (let i = 0; i < 3; i++) { const d = Math.max(min[i] - e[i], 0, e[i] - max[i]); s += d * d; }
  return Math.sqrt(s);
}

// True when the AABB lies entirely outside one frustum plane (the usual conservative cull test).
export function aabbOutsideFrustum(cam, min, max) {
  const { f, r, u, tanX, tanY } = cameraBasis(cam);
  const e = cam.eye;
  // planes as (normal n, offset k): inside iff dot(n, p - e) >= k
  const planes = [
    [add(r, scale(f, tanX)), 0], [add(scale(r, -1), scale(f, tanX)), 0],
    [add(u, scale(f, tanY)), 0], [add(scale(u, -1), scale(f, tanY)), 0],
    [f, cam.near], [scale(f, -1), -cam.far],
  ];
  for (const [n, k] of planes) {
    const pv = [0, 1, 2].map((i) => (n[i] >= 0 ? max[i] : min[i])); // the corner furthest along n
    if (dot(n, sub(pv, e)) < k) return true;
  }
  return false;
}

// ---- images --------------------------------------------------------------------------------------

export const readPng = (f) => pngjs.PNG.sync.read(fs.readFileSync(f));
export function psnr(a, b) {
  if (a.width !== b.width || a.height !== b.height) return { error: `size ${a.width}x${a.height} vs ${b.width}x${b.height}` };
  let se = 0;
  for (let i = 0; i < a.data.length; i += 4)
    for (let c = 0; c < 3; c++) { const d = a.data[i + c] - b.data[i + c]; se += d * d; }
  const mse = se / (a.width * a.height * 3);
  return { psnr: mse === 0 ? Infinity : +(10 * Math.log10((255 * 255) / mse)).toFixed(2) };
}
