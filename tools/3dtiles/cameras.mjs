// Derives three cameras (overview, mid, street) from an exported tileset's bounds and writes
//   OUT/{name}.path.json  atlastree keyframe camera files (for `atlastree render --path`)
//   OUT/cams.json         check.mjs cameras, expecting OUT/sel-{name}/selection.json and
//                         OUT/sel-{name}/frame_0000.png (what `atlastree render --selection --out
//                         OUT/sel-{name}` writes)
// usage: node tools/3dtiles/cameras.mjs --tileset DIR --out OUT [--width 800 --height 600 --fov 60]
//        node tools/3dtiles/cameras.mjs --from cams.json --out OUT   (given cameras, same outputs)
// Bounds: the union of atlastree-export.json's per-tile scene AABBs, else the root box (scene y-up).
import fs from 'node:fs';
import path from 'node:path';
import { parseArgs } from 'node:util';
import { exportTiles, norm, add, scale } from './lib.mjs';

const { values: opt } = parseArgs({
  options: { tileset: { type: 'string' }, from: { type: 'string' }, out: { type: 'string' }, width: { type: 'string', default: '800' },
    height: { type: 'string', default: '600' }, fov: { type: 'string', default: '60' } },
});
if (!(opt.tileset || opt.from) || !opt.out) { console.error('usage: node cameras.mjs (--tileset DIR | --from cams.json) --out OUT'); process.exit(2); }
const W = +opt.width, H = +opt.height, FOV = +opt.fov;

// atlastree's keyframe camera file (scene y-up; fov horizontal, degrees) and check.mjs's entry
function write(list) {
  fs.mkdirSync(opt.out, { recursive: true });
  const out = list.map((c) => {
    const kf = { time: 0, eye: c.eye, target: c.target, fov: c.fov };
    fs.writeFileSync(path.join(opt.out, `${c.name}.path.json`), JSON.stringify({
      keyframes: [kf, { ...kf, time: 1 }], up: c.up, aspect: c.width / c.height, near: c.near, far: c.far,
    }, null, 1));
    return { ...c, expected_selection: `sel-${c.name}/selection.json`, reference_png: `sel-${c.name}/frame_0000.png` };
  });
  fs.writeFileSync(path.join(opt.out, 'cams.json'), JSON.stringify(out, null, 1));
  console.log(`cameras ${out.map((c) => `${c.name} ${c.width}x${c.height}`).join(', ')} in ${opt.out}`);
}
if (opt.from) {
  const base = { up: [0, 1, 0], fov: FOV, near: 0.25, far: 100000, width: W, height: H };
  write(JSON.parse(fs.readFileSync(opt.from, 'utf8')).map(({ name, expected_selection, reference_png, ...c }) => ({ name, ...base, ...c })));
  process.exit(0);
}

let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
const ex = path.join(opt.tileset, 'atlastree-export.json');
const list = fs.existsSync(ex) ? exportTiles(JSON.parse(fs.readFileSync(ex, 'utf8'))) : [];
for (const t of list) for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], t.bounds_min[k]); hi[k] = Math.max(hi[k], t.bounds_max[k]); }
if (!list.length) { // root box (z-up, assumed axis-aligned) -> y-up AABB
  const b = JSON.parse(fs.readFileSync(path.join(opt.tileset, 'tileset.json'), 'utf8')).root.boundingVolume.box;
  const c = [b[0], b[2], -b[1]], h = [Math.abs(b[3]), Math.abs(b[11]), Math.abs(b[7])];
  lo = c.map((v, k) => v - h[k]); hi = c.map((v, k) => v + h[k]);
}
const size = hi.map((v, k) => v - lo[k]);
const diag = Math.hypot(size[0], size[2]);
const ground = [(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2];

const cams = {
  // the whole footprint in a 60° view, from the +z side, ~37° down
  overview: { eye: add(ground, scale(norm([0, 0.6, 0.8]), 1.1 * diag)), target: ground },
  // closer, oblique: a mix of levels
  mid: { eye: add(ground, scale(norm([0.4, 0.5, 0.75]), 0.35 * diag)), target: ground },
  // 1.7 m above the ground, 2 m outside the footprint's +z edge, looking in (originals nearby)
  street: {
    eye: [ground[0] + 0.1 * size[0], lo[1] + 1.7, hi[2] + 2],
    target: [ground[0] + 0.1 * size[0], lo[1] + 6, ground[2]],
  },
};
const round = (p) => p.map((v) => +v.toFixed(3));
console.log(`bounds ${round(lo)} .. ${round(hi)}`);
write(Object.entries(cams).map(([name, c]) => ({ name, eye: round(c.eye), target: round(c.target), up: [0, 1, 0],
  fov: FOV, near: 0.25, far: 100000, width: W, height: H })));
