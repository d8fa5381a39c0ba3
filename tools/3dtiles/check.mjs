// Checks an exported tileset in headless Chromium with 3DTilesRendererJS and CesiumJS.
//   node tools/3dtiles/check.mjs --tileset DIR --cameras cams.json --out OUTDIR
//        [--viewers 3dtr,cesium] [--min-psnr DB] [--timeout S] [--tolerance 0.08] [--chromium PATH]
// cams.json: [{ name, eye, target, up, fov (horizontal deg), near, far, width, height,
//               expected_selection?: selection.json of `atlastree render --selection`,
//               reference_png?: frame_0000.png }]   (paths relative to cams.json; scene y-up frame)
// Writes OUTDIR/{viewer}-{camera}.png and OUTDIR/report.json, prints a table. Exit 1 on: a console
// error, a blank screenshot, a selection mismatch not explained by the tolerance rule, a PSNR below
// --min-psnr, a run that does not settle; exit 2 on bad usage.
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { parseArgs } from 'node:util';
import { execFileSync } from 'node:child_process';
import puppeteer from 'puppeteer-core';
import { startServer } from './serve.mjs';
import { loadTileset, itemKey, exportTiles, aabbDistance, aabbOutsideFrustum, BACKGROUND_SRGB, readPng, psnr } from './lib.mjs';

const { values: opt } = parseArgs({
  options: {
    tileset: { type: 'string' }, cameras: { type: 'string' }, out: { type: 'string' },
    viewers: { type: 'string', default: '3dtr,cesium' }, 'min-psnr': { type: 'string', default: '0' },
    timeout: { type: 'string', default: '90' }, tolerance: { type: 'string', default: '0.08' },
    chromium: { type: 'string' },
  },
});
if (!opt.tileset || !opt.cameras || !opt.out) {
  console.error('usage: node check.mjs --tileset DIR --cameras cams.json --out OUTDIR [--viewers 3dtr,cesium] [--min-psnr DB]');
  process.exit(2);
}
const VIEWERS = { '3dtr': 'view-3dtr.html', cesium: 'view-cesium.html' };
const viewers = opt.viewers.split(',').filter(Boolean);
for (const v of viewers) if (!VIEWERS[v]) { console.error(`unknown viewer ${v}`); process.exit(2); }
const MIN_PSNR = +opt['min-psnr'], TOL = +opt.tolerance;
const tilesetDir = path.resolve(opt.tileset), outDir = path.resolve(opt.out);
const camsDir = path.dirname(path.resolve(opt.cameras));
const cams = JSON.parse(fs.readFileSync(opt.cameras, 'utf8'));
fs.mkdirSync(outDir, { recursive: true });

// Console lines that are known noise (still listed in the report under `ignored`)
const IGNORED = [
  /GPU stall due to ReadPixels/,
  /tiles versions at 1\.1 or higher have limited support/, // 3DTilesRendererJS on any 1.1 tileset
  /Automatic fallback to software WebGL has been deprecated/,
  // 3DTilesRendererJS aborts downloads of tiles that stopped being needed (AbortController)
  /^request failed: .* net::ERR_ABORTED$/,
];

// ---- the tile tree by (tree/node/source), with atlastree's min_distance and scene AABBs ----
const model = new Map(); // key -> { parent, children: Set, min_distance, bmin, bmax }
{
  const { tiles } = loadTileset(tilesetDir, { onError: (m) => { console.error(`cannot read the tileset: ${m}`); process.exit(1); } });
  const keyOf = (t) => { const id = t.extras?.atlastree ?? t.ident; return id ? itemKey(id) : null; };
  for (const t of tiles) {
    const k = keyOf(t);
    if (!k) continue;
    let p = t.parent; // nearest ancestor with an identity (contentless grouping tiles are skipped)
    while (p != null && !keyOf(tiles[p])) p = tiles[p].parent;
    const pk = p == null ? null : keyOf(tiles[p]);
    model.set(k, { ...(model.get(k) || { children: new Set() }), parent: pk });
    if (pk) { if (!model.has(pk)) model.set(pk, { children: new Set() }); model.get(pk).children.add(k); }
  }
  const ex = path.join(tilesetDir, 'atlastree-export.json');
  if (fs.existsSync(ex)) {
    const exp = JSON.parse(fs.readFileSync(ex, 'utf8'));
    for (const t of exportTiles(exp)) {
      const m = model.get(itemKey(t));
      if (m) Object.assign(m, { min_distance: t.min_distance, bmin: t.bounds_min, bmax: t.bounds_max });
    }
  }
}

// ---- selection comparison ----
// A mismatch is explained when the viewer and atlastree differ by one level (parent vs its child)
// and the eye is within TOL of the parent's switching distance (distance to its AABB vs its
// min_distance), or when atlastree lists a node whose AABB is entirely outside the frustum.
function compareSelection(cam, visible, expectedFile) {
  const frame = JSON.parse(fs.readFileSync(expectedFile, 'utf8')).frames[0];
  const E = new Set(frame.items.map(itemKey));
  // atlastree rescales min_distance to the render's viewing conditions (width, texel ratio): `scale`
  const sc = frame.scale ?? 1;
  // sanity: atlastree's own eye-to-AABB distances against ours (camera and bounds agree?)
  let maxDistanceDiff = 0;
  for (const it of frame.items) {
    const m = model.get(itemKey(it));
    if (it.distance != null && m?.bmin) maxDistanceDiff = Math.max(maxDistanceDiff, Math.abs(aabbDistance(cam.eye, m.bmin, m.bmax) - it.distance));
  }
  const V = new Set(visible.map(itemKey));
  const onlyV = [...V].filter((k) => !E.has(k)), onlyE = new Set([...E].filter((k) => !V.has(k)));
  const accounted = new Set(), mismatches = [];
  const switching = (pk) => {
    const m = model.get(pk);
    if (!m || m.min_distance == null) return { reason: 'no min_distance/bounds for the parent (atlastree-export.json)' };
    const d = aabbDistance(cam.eye, m.bmin, m.bmax);
    const sw = m.min_distance * sc, rel = (d - sw) / sw;
    return { parent: pk, distance: +d.toFixed(3), switching_distance: +sw.toFixed(3), rel: +rel.toFixed(4), explained: Math.abs(rel) <= TOL };
  };
  for (const k of onlyV) {
    const m = model.get(k);
    if (!m) { mismatches.push({ viewer: k, kind: 'not in tileset', explained: false }); continue; }
    if (m.parent && onlyE.has(m.parent)) {
      accounted.add(m.parent);
      mismatches.push({ viewer: k, atlastree: m.parent, kind: 'viewer finer', ...switching(m.parent) });
      continue;
    }
    const kids = [...m.children].filter((c) => onlyE.has(c));
    if (kids.length) {
      kids.forEach((c) => accounted.add(c));
      mismatches.push({ viewer: k, atlastree: kids.join(' '), kind: 'viewer coarser', ...switching(k) });
      continue;
    }
    mismatches.push({ viewer: k, kind: 'only in viewer', explained: false });
  }
  for (const k of onlyE) {
    if (accounted.has(k)) continue;
    const m = model.get(k);
    if (m?.bmin && aabbOutsideFrustum(cam, m.bmin, m.bmax)) mismatches.push({ atlastree: k, kind: 'outside frustum', explained: true });
    else mismatches.push({ atlastree: k, kind: 'only in atlastree', explained: false });
  }
  return { scale: sc, max_distance_diff: +maxDistanceDiff.toFixed(6), expected: E.size, visible: V.size, matched: [...V].filter((k) => E.has(k)).length, mismatches,
    unexplained: mismatches.filter((m) => !m.explained).length };
}

// ---- images ----
function nonBackground(img) { // fraction of pixels whose colour differs from the background by > 10
  let n = 0;
  for (let i = 0; i < img.data.length; i += 4)
    if (BACKGROUND_SRGB.some((v, c) => Math.abs(img.data[i + c] - v) > 10)) n++;
  return n / (img.width * img.height);
}

// ---- browser ----
function chromiumPath() {
  if (opt.chromium) return opt.chromium;
  if (process.env.CHROMIUM) return process.env.CHROMIUM;
  try { return execFileSync('sh', ['-c', 'command -v chromium || command -v chromium-browser'], { encoding: 'utf8' }).trim(); }
  catch { console.error('no chromium: apt-get install -y --no-install-recommends chromium'); process.exit(2); }
}
const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'harness-chromium-'));
let server, browser, cleaning = null;
const cleanup = () => (cleaning ??= (async () => { // idempotent: signal handler and `finally` both call it
  try { await browser?.close(); } catch {}
  try { await server?.close(); } catch {}
  fs.rmSync(profile, { recursive: true, force: true });
})());
for (const sig of ['SIGINT', 'SIGTERM', 'SIGHUP']) process.on(sig, () => cleanup().then(() => process.exit(130)));

async function runOne(viewer, cam) {
  const page = await browser.newPage();
  const consoleLines = [];
  page.on('console', (m) => { if (['error', 'warn', 'warning', 'assert'].includes(m.type())) consoleLines.push({ level: m.type() === 'assert' ? 'error' : m.type().replace('warning', 'warn'), text: m.text() }); });
  page.on('pageerror', (e) => consoleLines.push({ level: 'error', text: `pageerror: ${e.message}` }));
  page.on('requestfailed', (r) => consoleLines.push({ level: 'error', text: `request failed: ${r.url()} ${r.failure()?.errorText}` }));
  page.on('response', (r) => { if (r.status() >= 400) consoleLines.push({ level: 'error', text: `HTTP ${r.status()} ${r.url()}` }); });
  await page.setViewport({ width: cam.width, height: cam.height, deviceScaleFactor: 1 });
  const camera = { eye: cam.eye, target: cam.target, up: cam.up || [0, 1, 0], fov: cam.fov, near: cam.near, far: cam.far, width: cam.width, height: cam.height };
  const cfg = { tileset: '/tiles/tileset.json', camera, stableFrames: 5 };
  const t0 = Date.now();
  await page.goto(`${server.url}/${VIEWERS[viewer]}?cfg=${encodeURIComponent(JSON.stringify(cfg))}`);
  let result = null, failure = null;
  try {
    await page.waitForFunction(() => window.__harness && window.__harness.result, { timeout: +opt.timeout * 1000, polling: 100 });
    result = await page.evaluate(() => window.__harness.result);
  } catch (e) {
    const progress = await page.evaluate(() => window.__harness && window.__harness.progress).catch(() => null);
    failure = `did not settle within ${opt.timeout} s (${e.message.split('\n')[0]}); progress ${JSON.stringify(progress)}`;
  }
  const ms = Date.now() - t0;
  const shot = path.join(outDir, `${viewer}-${cam.name}.png`);
  await page.screenshot({ path: shot, clip: { x: 0, y: 0, width: cam.width, height: cam.height } });
  await page.close();
  const ignored = consoleLines.filter((l) => IGNORED.some((re) => re.test(l.text)));
  const rest = consoleLines.filter((l) => !ignored.includes(l));
  return { viewer, camera: cam.name, ms, page_ms: result?.ms, frames: result?.frames, screenshot: shot, failure,
    tiles: result?.tiles ?? [], notes: result?.notes ?? [],
    console: { errors: rest.filter((l) => l.level === 'error').map((l) => l.text),
      warnings: rest.filter((l) => l.level !== 'error').map((l) => l.text), ignored: ignored.map((l) => l.text) } };
}

// ---- main ----
const runs = [];
try {
  server = await startServer(tilesetDir);
  browser = await puppeteer.launch({
    executablePath: chromiumPath(), headless: true, userDataDir: profile,
    handleSIGINT: false, handleSIGTERM: false, handleSIGHUP: false, // ours close browser and server
    args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--disable-gpu-sandbox',
      '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run',
      '--disable-quic', '--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1'],
  });
  for (const cam of cams) {
    for (const viewer of viewers) {
      const r = await runOne(viewer, cam);
      const fails = r.failure ? [r.failure] : [];
      if (r.console.errors.length) fails.push(`${r.console.errors.length} console error(s)`);
      for (const t of r.tiles) if (t.conflict) fails.push(`tile ${t.uri}: ${t.conflict}`);
      const img = readPng(r.screenshot);
      r.non_background = +nonBackground(img).toFixed(4);
      if (r.non_background <= 0.05) fails.push(`blank screenshot (${(r.non_background * 100).toFixed(1)} % non-background)`);
      if (cam.expected_selection && !r.failure) {
        r.selection = compareSelection(cam, r.tiles, path.resolve(camsDir, cam.expected_selection));
        if (r.selection.unexplained) fails.push(`${r.selection.unexplained} unexplained selection mismatch(es)`);
        // a different camera or scene placement shows as distances that disagree (report only)
        if (r.selection.max_distance_diff > 0.01) r.notes.push(`atlastree's distances differ from ours by up to ${r.selection.max_distance_diff}`);
      }
      if (cam.reference_png) {
        const p = psnr(img, readPng(path.resolve(camsDir, cam.reference_png)));
        r.psnr = p.psnr ?? null;
        if (p.error) fails.push(`reference: ${p.error}`);
        else if (r.psnr < MIN_PSNR) fails.push(`PSNR ${r.psnr} dB < ${MIN_PSNR}`);
      }
      r.failures = fails;
      runs.push(r);
    }
  }
} catch (e) {
  if (cleaning) await new Promise(() => {}); // interrupted: the signal handler exits
  throw e;
} finally {
  await cleanup();
}
// the two viewers against each other (report only)
const cross = cams.map((cam) => {
  const [a, b] = viewers.map((v) => runs.find((r) => r.viewer === v && r.camera === cam.name));
  return a && b ? { camera: cam.name, viewers: `${a.viewer}/${b.viewer}`, psnr: psnr(readPng(a.screenshot), readPng(b.screenshot)).psnr } : null;
}).filter(Boolean);
const ok = runs.every((r) => r.failures.length === 0);
const report = { tileset: tilesetDir, cameras: path.resolve(opt.cameras), tolerance: TOL, min_psnr: MIN_PSNR, ok, runs, cross };
// JSON has no Infinity (identical images): written as "inf"
fs.writeFileSync(path.join(outDir, 'report.json'), JSON.stringify(report, (k, v) => (v === Infinity ? 'inf' : v), 1));

// ---- table ----
const rows = [['viewer', 'camera', 'ms', 'tiles', 'selection', 'PSNR', 'non-bg', 'err/warn', 'result']];
for (const r of runs) {
  const s = r.selection;
  const sel = !s ? '-' : [`${s.matched}/${s.expected}`, s.mismatches.length > s.unexplained ? `${s.mismatches.length - s.unexplained} tol` : '',
    s.unexplained ? `${s.unexplained} BAD` : ''].filter(Boolean).join(' ');
  rows.push([r.viewer, r.camera, String(r.ms), String(r.tiles.length), sel, r.psnr == null ? '-' : r.psnr === Infinity ? 'inf' : String(r.psnr),
    `${(r.non_background * 100).toFixed(1)}%`, `${r.console.errors.length}/${r.console.warnings.length}`,
    r.failures.length ? 'FAIL' : 'ok']);
}
const wd = rows[0].map((_, i) => Math.max(...rows.map((r) => r[i].length)));
for (const r of rows) console.log(r.map((c, i) => c.padEnd(wd[i])).join('  '));
for (const c of cross) console.log(`cross ${c.camera} ${c.viewers}: PSNR ${c.psnr} dB`);
for (const r of runs) {
  for (const n of r.notes) console.log(`note ${r.viewer}-${r.camera}: ${n}`);
  for (const f of r.failures) console.log(`FAIL ${r.viewer}-${r.camera}: ${f}`);
  for (const e of r.console.errors.slice(0, 5)) console.log(`  error: ${e}`);
  for (const m of r.selection?.mismatches ?? []) if (!m.explained) console.log(`  mismatch: ${JSON.stringify(m)}`);
}
console.log(`${ok ? 'OK' : 'FAILED'}; report: ${path.join(outDir, 'report.json')}`);
process.exit(ok ? 0 : 1);
