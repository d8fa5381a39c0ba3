// Validates an exported tileset: every .gltf/.glb with the Khronos glTF-Validator (external buffers
// and images read relative to the .gltf), plus the tileset-level checks the project needs (the
// official 3d-tiles-validator is not on the npm registry): the 3D Tiles 1.1 JSON schema (schema-check.mjs);
//   asset.version "1.1"; the root has refine; child geometricError <= parent's; every content URI
//   resolves; extras.atlastree agrees with the URI; each content's positions (accessor min/max through
//   the glTF node transforms, y-up -> z-up, through the tile transforms) lie inside its tile's box
//   (1e-3 relative tolerance).
// usage: node tools/3dtiles/validate.mjs DIR [--json report.json] [--verbose]
// Prints per-file error/warning counts (files with issues; all with --verbose); exit 1 on any error.
import fs from 'node:fs';
import path from 'node:path';
import { parseArgs } from 'node:util';
import validator from 'gltf-validator';
import { schemaErrors } from './schema-check.mjs';
import { loadTileset, itemKey, exportTiles, trs, mul, apply, corners, yUpToZUp, insideBox, IDENTITY } from './lib.mjs';

const { values: opt, positionals } = parseArgs({
  allowPositionals: true,
  options: { json: { type: 'string' }, verbose: { type: 'boolean', default: false } },
});
if (positionals.length !== 1) { console.error('usage: node validate.mjs TILESET_DIR [--json FILE] [--verbose]'); process.exit(2); }
const DIR = path.resolve(positionals[0]);
const t0 = Date.now();
const problems = []; // tileset-level { severity: 'error'|'warning', code, where, message }
const err = (code, where, message) => problems.push({ severity: 'error', code, where, message });
const warn = (code, where, message) => problems.push({ severity: 'warning', code, where, message });

// ---- tileset structure ----
const { tilesets, tiles } = loadTileset(DIR, { onError: (m) => err('TILESET_UNREADABLE', m, m) });
for (const { file, json } of tilesets) {
  // The 3D Tiles 1.1 JSON schema (vendored, schema/NOTICE.md).
  for (const e of schemaErrors(json)) err('SCHEMA', `${file}${e.where}`, e.message);
  if (json.asset?.version !== '1.1') err('ASSET_VERSION', file, `asset.version is ${JSON.stringify(json.asset?.version)}, want "1.1"`);
  if (json.geometricError == null || json.geometricError < (json.root?.geometricError ?? 0))
    warn('TILESET_ERROR_BELOW_ROOT', file, `top-level geometricError ${json.geometricError} < root's ${json.root?.geometricError}`);
}
const where = (t) => `${t.file}#tile${t.id}${t.uri ? ` (${t.uri})` : ''}`;
if (tiles.length && !tiles[0].ownRefine) err('TILE_REFINE_MISSING_IN_ROOT', where(tiles[0]), 'the root tile has no refine');
const exportJson = fs.existsSync(path.join(DIR, 'atlastree-export.json'))
  ? JSON.parse(fs.readFileSync(path.join(DIR, 'atlastree-export.json'), 'utf8')) : null;
if (!exportJson) warn('NO_EXPORT_SUMMARY', 'atlastree-export.json', 'missing (check.mjs needs it for the tolerance rule)');
const W = exportJson?.screen_width, FOV = exportJson?.fov_x_deg;
const referenced = new Set();
for (const t of tiles) {
  if (t.refine && !['ADD', 'REPLACE'].includes(t.refine)) err('TILE_REFINE_INVALID', where(t), `refine ${t.refine}`);
  if (typeof t.geometricError !== 'number' || t.geometricError < 0) err('TILE_GEOMETRIC_ERROR', where(t), `geometricError ${t.geometricError}`);
  const p = t.parent != null ? tiles[t.parent] : null;
  if (p && t.geometricError > p.geometricError) err('TILE_GEOMETRIC_ERROR_ABOVE_PARENT', where(t), `${t.geometricError} > parent's ${p.geometricError}`);
  if (!t.box) warn('BOUNDING_VOLUME_NOT_BOX', where(t), `bounding volume ${Object.keys(t.boundingVolume || {})} not checked`);
  if (!t.uri) continue;
  referenced.add(t.uri);
  if (!fs.existsSync(path.join(DIR, t.uri))) { err('CONTENT_URI_UNRESOLVED', where(t), `${t.uri} does not exist`); continue; }
  if (t.uri.endsWith('.json')) continue;
  const a = t.extras?.atlastree;
  if (!t.ident) warn('CONTENT_URI_UNNAMED', where(t), 'content URI is not t{T}/n{N}[-orig].gltf');
  if (!a) warn('EXTRAS_MISSING', where(t), 'no extras.atlastree');
  if (a && t.ident && itemKey(a) !== itemKey(t.ident)) err('EXTRAS_URI_CONFLICT', where(t), `extras ${itemKey(a)} vs URI ${itemKey(t.ident)}`);
  if ((a?.source ?? t.ident?.source) === 'original' && t.geometricError !== 0) warn('ORIGINAL_ERROR_NONZERO', where(t), `geometricError ${t.geometricError}`);
  if (a && W && FOV && (a.source === 'atlas')) { // contract: g = min_distance * 2 tan(fov_x/2) * 16 / W
    const g = (a.min_distance * 2 * Math.tan((FOV * Math.PI) / 360) * 16) / W;
    if (Math.abs(g - t.geometricError) > 1e-6 * Math.max(1, g)) warn('GEOMETRIC_ERROR_FORMULA', where(t), `${t.geometricError}, formula gives ${g}`);
  }
}

// ---- glTF files ----
const files = [];
(function walk(d) {
  for (const e of fs.readdirSync(d, { withFileTypes: true })) {
    const f = path.join(d, e.name);
    if (e.isDirectory()) walk(f);
    else if (/\.(gltf|glb)$/i.test(e.name)) files.push(path.relative(DIR, f).split(path.sep).join('/'));
  }
})(DIR);
for (const f of files) if (!referenced.has(f)) warn('CONTENT_UNREFERENCED', f, 'no tile references this file');

// external buffers/images are shared by many .gltf files: keep them in memory (bounded)
const cache = new Map(); let cached = 0;
function readCached(file) {
  if (cache.has(file)) return cache.get(file);
  const data = new Uint8Array(fs.readFileSync(file));
  if (cached + data.length < 1 << 30) { cache.set(file, data); cached += data.length; }
  return data;
}
const byUri = new Map(tiles.filter((t) => t.uri).map((t) => [t.uri, t]));
const perFile = [];
const codes = new Map();
for (const f of files) {
  const full = path.join(DIR, f);
  const bytes = readCached(full);
  const report = await validator.validateBytes(bytes, {
    uri: f, maxIssues: 50, writeTimestamp: false,
    severityOverrides: { IMAGE_UNRECOGNIZED_FORMAT: 0 }, // a warning by default; the viewers cannot draw it
    externalResourceFunction: (uri) => new Promise((resolve, reject) => {
      try { resolve(readCached(path.resolve(path.dirname(full), decodeURIComponent(uri)))); } catch (e) { reject(e.message); }
    }),
  }).catch((e) => ({ issues: { numErrors: 1, numWarnings: 0, numInfos: 0, messages: [{ code: 'VALIDATOR_FAILED', message: String(e), severity: 0 }] } }));
  const is = report.issues;
  for (const m of is.messages) if (m.severity <= 1) codes.set(m.code, (codes.get(m.code) || 0) + 1);
  perFile.push({ file: f, errors: is.numErrors, warnings: is.numWarnings, infos: is.numInfos,
    messages: is.messages.filter((m) => m.severity <= 1).map((m) => `${['error', 'warning'][m.severity]} ${m.code} ${m.pointer ?? ''}: ${m.message}`) });
  // content inside its tile's box
  const t = byUri.get(f);
  if (!t || !t.box || is.numErrors) continue;
  const g = f.endsWith('.gltf') ? JSON.parse(Buffer.from(bytes).toString('utf8')) : null;
  if (!g) continue; // .glb: JSON chunk not parsed here (the exporter writes .gltf)
  let outside = 0, checked = 0, worst = null;
  const visit = (ni, parentM) => {
    const n = g.nodes[ni], m = mul(parentM, trs(n));
    for (const prim of n.mesh != null ? g.meshes[n.mesh].primitives : []) {
      const acc = g.accessors[prim.attributes.POSITION];
      if (!acc?.min || !acc?.max) { err('POSITION_MIN_MAX_MISSING', f, 'POSITION accessor has no min/max'); continue; }
      for (const c of corners(acc.min, acc.max)) {
        const p = apply(t.world, yUpToZUp(apply(m, c)));
        checked++;
        if (!insideBox(p, t.box, t.world)) { outside++; worst ??= p; }
      }
    }
    for (const ch of n.children || []) visit(ch, m);
  };
  for (const ni of g.scenes?.[g.scene ?? 0]?.nodes ?? []) visit(ni, IDENTITY);
  if (outside) err('CONTENT_OUTSIDE_TILE_BOX', where(t), `${outside}/${checked} accessor-bound corners outside the box, e.g. ${worst.map((v) => v.toFixed(3))}`);
}

// ---- atlastree-export.json vs the tileset ----
if (exportJson) {
  const byKey = new Map(tiles.filter((t) => t.ident).map((t) => [itemKey(t.extras?.atlastree ?? t.ident), t]));
  for (const e of exportTiles(exportJson)) {
    const t = byKey.get(itemKey(e));
    if (!t) { err('EXPORT_TILE_MISSING', itemKey(e), `atlastree-export.json lists ${e.uri}, the tileset has no such tile`); continue; }
    if (e.uri && e.uri !== t.uri) warn('EXPORT_URI_DIFFERS', itemKey(e), `${e.uri} vs ${t.uri}`);
    if (t.box && e.bounds_min && corners(e.bounds_min, e.bounds_max).some((c) => !insideBox(yUpToZUp(c), t.box, t.world)))
      err('EXPORT_BOUNDS_OUTSIDE_BOX', where(t), 'bounds_min/bounds_max (scene frame) are not inside the tile box');
  }
}

// ---- report ----
const totals = {
  files: perFile.length, gltf_errors: perFile.reduce((s, f) => s + f.errors, 0), gltf_warnings: perFile.reduce((s, f) => s + f.warnings, 0),
  tileset_errors: problems.filter((p) => p.severity === 'error').length, tileset_warnings: problems.filter((p) => p.severity === 'warning').length,
  tiles: tiles.length, tilesets: tilesets.length, seconds: +((Date.now() - t0) / 1000).toFixed(2),
};
for (const f of perFile) {
  if (!opt.verbose && !f.errors && !f.warnings) continue;
  console.log(`${f.file}: ${f.errors} error(s), ${f.warnings} warning(s), ${f.infos} info(s)`);
  for (const m of f.messages.slice(0, opt.verbose ? 50 : 3)) console.log(`    ${m}`);
}
if (codes.size) console.log(`glTF issue codes: ${[...codes].map(([c, n]) => `${c}×${n}`).join(', ')}`);
const shown = new Map();
for (const p of problems) { // at most 5 lines per code
  const n = (shown.get(p.code) || 0) + 1; shown.set(p.code, n);
  if (n <= 5 || opt.verbose) console.log(`${p.severity} ${p.code} ${p.where}: ${p.message}`);
  else if (n === 6) console.log(`  … more ${p.code} (see --json)`);
}
console.log(`${totals.files} glTF files: ${totals.gltf_errors} errors, ${totals.gltf_warnings} warnings; ` +
  `${totals.tiles} tiles in ${totals.tilesets} tileset(s): ${totals.tileset_errors} errors, ${totals.tileset_warnings} warnings; ${totals.seconds} s`);
if (opt.json) fs.writeFileSync(opt.json, JSON.stringify({ dir: DIR, totals, problems, files: perFile }, null, 1));
const ok = !totals.gltf_errors && !totals.tileset_errors;
console.log(ok ? 'VALID' : 'INVALID');
process.exit(ok ? 0 : 1);
