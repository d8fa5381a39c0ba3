// What a viewer holds of an atlastree 3D Tiles export at the cameras of a ci-test.sh run, beside the naive
// export (every tile with the original textures, `atlastree export 3dtiles --naive`), and how close the
// viewers' screenshots come to atlastree's own frames (tree and original textures).
//   node tools/3dtiles/measure.mjs --work WORK --naive NAIVE_DIR [--json OUT.json]
// WORK: a ci-test.sh work dir (tiles/, cams/sel-NAME/{selection.json,frame_0000.png}, check/{viewer}-NAME.png),
// optionally cams/tree-NAME/frame_0000.png (`atlastree render --mode tree`) for the PSNR against the tree.
// "Held" = the distinct images of the tiles drawn at the camera (atlastree's selection, which the viewers
// were checked to show), as RGBA8 with mips (4/3 · 4 bytes per texel): what the viewer's GPU holds for them.
import fs from 'node:fs';
import path from 'node:path';
import { parseArgs } from 'node:util';
import { readPng, psnr as psnrOf } from './lib.mjs';

const { values: opt } = parseArgs({ options: { work: { type: 'string' }, naive: { type: 'string' }, json: { type: 'string' } } });
if (!opt.work || !opt.naive) { console.error('usage: node measure.mjs --work WORK --naive NAIVE_DIR [--json OUT]'); process.exit(2); }
const readJson = (f) => JSON.parse(fs.readFileSync(f, 'utf8'));
const tiles = readJson(path.join(opt.work, 'tiles', 'atlastree-export.json'));
const naive = readJson(path.join(opt.naive, 'atlastree-export.json'));
const key = (t) => `${t.tree}/${t.node}/${t.source}`;
const index = (ex) => new Map(ex.tile_list.map((t) => [key(t), t]));
const [ti, ni] = [index(tiles), index(naive)];

function held(idx, items) {
  const imgs = new Map();
  let draws = 0;
  for (const it of items) {
    const t = idx.get(key(it));
    if (!t) throw new Error(`no tile ${key(it)}`);
    draws += t.draw_calls;
    for (const i of t.images) imgs.set(`${t.tree}/${i.uri}`, i);
  }
  let gpu = 0, bytes = 0;
  for (const i of imgs.values()) { gpu += i.gpu_bytes; bytes += i.bytes; }
  return { tiles: items.length, images: imgs.size, image_bytes: bytes, gpu_bytes: gpu, draw_calls: draws };
}

// PSNR (RGB, 8-bit) of two PNG files; null when one is missing or the sizes differ.
function psnr(fa, fb) {
  if (!fs.existsSync(fa) || !fs.existsSync(fb)) return null;
  return psnrOf(readPng(fa), readPng(fb)).psnr ?? null;
}

const mib = (b) => (b / 1048576).toFixed(2);
const cams = readJson(path.join(opt.work, 'cams', 'cams.json'));
const rows = [];
for (const cam of cams) {
  const sel = readJson(path.join(opt.work, 'cams', `sel-${cam.name}`, 'selection.json'));
  const items = sel.frames[0].items;
  const row = { camera: cam.name, tree: held(ti, items), naive: held(ni, items), psnr: {} };
  for (const v of ['3dtr', 'cesium']) {
    const shot = path.join(opt.work, 'check', `${v}-${cam.name}.png`);
    row.psnr[v] = {
      original: psnr(shot, path.join(opt.work, 'cams', `sel-${cam.name}`, 'frame_0000.png')),
      tree: psnr(shot, path.join(opt.work, 'cams', `tree-${cam.name}`, 'frame_0000.png')),
    };
  }
  row.psnr.atlastree_tree_vs_original = psnr(path.join(opt.work, 'cams', `tree-${cam.name}`, 'frame_0000.png'),
    path.join(opt.work, 'cams', `sel-${cam.name}`, 'frame_0000.png'));
  rows.push(row);
}
const totals = (ex) => ({ total_bytes: ex.total_bytes, image_bytes: ex.image_bytes, geometry_bytes: ex.geometry_bytes,
  per_tile_geometry_bytes: ex.per_tile_geometry_bytes, tiles: ex.tiles, images: ex.images, paging_file_bytes: ex.paging_file_bytes });
const out = { source: tiles.source, tree: totals(tiles), naive: totals(naive), cameras: rows };
console.log(`${tiles.source}: tileset ${mib(tiles.total_bytes)} MiB (images ${mib(tiles.image_bytes)}, geometry ${mib(tiles.geometry_bytes)} once, ${mib(tiles.per_tile_geometry_bytes)} if per tile), naive ${mib(naive.total_bytes)} MiB, paging file ${mib(tiles.paging_file_bytes)} MiB; ${tiles.tiles} tiles`);
console.log('camera    tiles  draws(tree/naive)  images(tree/naive)  GPU MiB tree  GPU MiB naive  PSNR 3dtr orig/tree  PSNR cesium orig/tree  atlastree tree/orig');
for (const r of rows)
  console.log(`${r.camera.padEnd(9)} ${String(r.tree.tiles).padStart(5)}  ${`${r.tree.draw_calls}/${r.naive.draw_calls}`.padStart(17)}  ${`${r.tree.images}/${r.naive.images}`.padStart(18)}  ${mib(r.tree.gpu_bytes).padStart(12)}  ${mib(r.naive.gpu_bytes).padStart(13)}  ${`${r.psnr['3dtr'].original}/${r.psnr['3dtr'].tree}`.padStart(19)}  ${`${r.psnr.cesium.original}/${r.psnr.cesium.tree}`.padStart(21)}  ${String(r.psnr.atlastree_tree_vs_original).padStart(19)}`);
if (opt.json) fs.writeFileSync(opt.json, JSON.stringify(out, null, 1));
