// Tiny static HTTP server on 127.0.0.1 (random free port).
//   /tiles/...        -> the tileset directory
//   /node_modules/... -> tools/3dtiles/node_modules
//   /...              -> tools/3dtiles (the viewer pages)
// Every 4xx is remembered in `misses` (a content URI that does not resolve shows up there).
// Standalone: node serve.mjs TILESET_DIR   (prints the URL, Ctrl-C stops)
import http from 'node:http';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const HERE = path.dirname(fileURLToPath(import.meta.url));
const MIME = {
  '.json': 'application/json', '.gltf': 'model/gltf+json', '.glb': 'model/gltf-binary',
  '.bin': 'application/octet-stream', '.png': 'image/png', '.jpg': 'image/jpeg', '.jpeg': 'image/jpeg',
  '.ktx2': 'image/ktx2', '.webp': 'image/webp', '.js': 'text/javascript', '.mjs': 'text/javascript',
  '.wasm': 'application/wasm', '.css': 'text/css', '.html': 'text/html; charset=utf-8',
  '.svg': 'image/svg+xml', '.xml': 'application/xml', '.map': 'application/json',
};

export function startServer(tilesetDir) {
  const mounts = [['/tiles/', path.resolve(tilesetDir)], ['/node_modules/', path.join(HERE, 'node_modules')], ['/', HERE]];
  const misses = [];
  const server = http.createServer((req, res) => {
    const url = decodeURIComponent(new URL(req.url, 'http://x').pathname);
    const [prefix, root] = mounts.find(([p]) => url.startsWith(p));
    const file = path.join(root, url.slice(prefix.length));
    const fail = (code) => { misses.push({ status: code, url }); res.writeHead(code).end(); };
    if (!file.startsWith(root)) return fail(403); // no ../ escapes
    fs.stat(file, (err, st) => {
      if (err || !st.isFile()) return fail(404);
      res.writeHead(200, {
        'Content-Type': MIME[path.extname(file).toLowerCase()] || 'application/octet-stream',
        'Content-Length': st.size,
        // library code may be cached (V8 code cache: later pages start faster); tiles never are
        'Cache-Control': prefix === '/node_modules/' ? 'public, max-age=3600' : 'no-store',
      });
      if (req.method === 'HEAD') return res.end();
      fs.createReadStream(file).pipe(res);
    });
  });
  return new Promise((resolve, reject) => {
    server.on('error', reject);
    server.listen(0, '127.0.0.1', () => {
      const url = `http://127.0.0.1:${server.address().port}`;
      // closeAllConnections: keep-alive sockets from the browser must not hold the process open
      resolve({ url, misses, close: () => new Promise((r) => { server.closeAllConnections(); server.close(r); }) });
    });
  });
}

if (process.argv[1] === fileURLToPath(import.meta.url)) {
  const s = await startServer(process.argv[2] || '.');
  console.log(`${s.url}/  (tileset: ${s.url}/tiles/tileset.json)`);
}
