// The client benchmark's delaying proxy and page server (Node, no dependencies).
//
//   node proxy.mjs --port P --upstream http://127.0.0.1:S [--delay-ms 30] [--static DIR]
//
// * Every request under /tiles/ and /layers is held DELAY ms, then forwarded to the upstream
//   tinstream-server over a keep-alive connection pool; the answer streams back unchanged
//   (status, headers, compressed body). So both clients, tinstream-viewer and CesiumJS, see a
//   server 30 ms away, with as many requests in flight as they choose to send.
// * It counts what it forwards: requests, answers by status, response bytes (status line, headers
//   and body as sent), and the most requests in flight at once. GET /__stats returns the counters
//   as JSON; GET /__reset zeroes them (before each measured run).
// * With --static DIR it serves DIR's files for every other path (the Cesium page and CesiumJS's
//   build), same origin as the tiles, so the page needs no CORS.
// Prints "listening PORT" on stdout once ready.
import http from 'node:http';
import fs from 'node:fs';
import path from 'node:path';

function arg(name, fallback) {
  const i = process.argv.indexOf(name);
  return i > 0 && i + 1 < process.argv.length ? process.argv[i + 1] : fallback;
}

const port = Number(arg('--port', '0'));
const upstream = new URL(arg('--upstream', 'http://127.0.0.1:8080'));
const delayMs = Number(arg('--delay-ms', '30'));
const staticDir = arg('--static', '') && path.resolve(arg('--static', ''));
const agent = new http.Agent({ keepAlive: true, maxSockets: 64 });

const zero = () => ({ requests: 0, status: {}, bytes: 0, body_bytes: 0, in_flight: 0,
                      max_in_flight: 0, by_kind: {} });
let stats = zero();

const types = { '.html': 'text/html', '.js': 'text/javascript', '.mjs': 'text/javascript',
                '.css': 'text/css', '.json': 'application/json', '.png': 'image/png',
                '.jpg': 'image/jpeg', '.svg': 'image/svg+xml', '.wasm': 'application/wasm',
                '.xml': 'application/xml', '.glb': 'model/gltf-binary', '.ktx2': 'image/ktx2' };

function serveStatic(req, res) {
  const url = new URL(req.url, 'http://x');
  const rel = path.normalize(decodeURIComponent(url.pathname)).replace(/^([/\\])+/, '');
  const file = path.join(staticDir, rel || 'index.html');
  if (!staticDir || !file.startsWith(staticDir)) {
    res.writeHead(404).end();
    return;
  }
  fs.stat(file, (err, st) => {
    if (err || !st.isFile()) {
      res.writeHead(404).end();
      return;
    }
    res.writeHead(200, { 'Content-Type': types[path.extname(file)] || 'application/octet-stream',
                         'Content-Length': st.size, 'Cache-Control': 'no-store' });
    fs.createReadStream(file).pipe(res);
  });
}

// Which kind of answer a tile path is (for the byte counters).
function kindOf(p) {
  if (p.startsWith('/layers')) return 'layers';
  if (p.endsWith('/layer.json')) return 'layer.json';
  if (p.endsWith('.terrain')) return 'terrain';
  return 'native';
}

function forward(req, res) {
  const kind = kindOf(new URL(req.url, 'http://x').pathname);
  stats.requests += 1;
  stats.in_flight += 1;
  stats.max_in_flight = Math.max(stats.max_in_flight, stats.in_flight);
  const counted = stats;  // a reset during the request starts a new set of counters
  const k = (counted.by_kind[kind] ??= { requests: 0, bytes: 0 });
  k.requests += 1;
  setTimeout(() => {
    const headers = { ...req.headers, host: upstream.host, connection: 'keep-alive' };
    const up = http.request({ host: upstream.hostname, port: upstream.port, path: req.url,
                              method: req.method, headers, agent }, (u) => {
      let head = `HTTP/1.1 ${u.statusCode} ${u.statusMessage}\r\n`;
      for (let i = 0; i < u.rawHeaders.length; i += 2)
        head += `${u.rawHeaders[i]}: ${u.rawHeaders[i + 1]}\r\n`;
      const headBytes = Buffer.byteLength(head) + 2;
      counted.bytes += headBytes;
      k.bytes += headBytes;
      counted.status[u.statusCode] = (counted.status[u.statusCode] || 0) + 1;
      const out = { ...u.headers };
      delete out.connection;
      delete out['keep-alive'];
      res.writeHead(u.statusCode, out);
      u.on('data', (chunk) => {
        counted.bytes += chunk.length;
        counted.body_bytes += chunk.length;
        k.bytes += chunk.length;
        res.write(chunk);
      });
      u.on('end', () => {
        counted.in_flight -= 1;
        res.end();
      });
    });
    up.on('error', (e) => {
      counted.in_flight -= 1;
      counted.status.error = (counted.status.error || 0) + 1;
      if (!res.headersSent) res.writeHead(502, { 'Content-Type': 'text/plain' });
      res.end(`proxy: ${e.message}\n`);
    });
    req.pipe(up);
  }, delayMs);
}

const server = http.createServer((req, res) => {
  const p = req.url.split('?')[0];
  if (p === '/__stats') {
    res.writeHead(200, { 'Content-Type': 'application/json' }).end(JSON.stringify(stats));
  } else if (p === '/__reset') {
    stats = zero();
    res.writeHead(200, { 'Content-Type': 'application/json' }).end('{}');
  } else if (p.startsWith('/tiles/') || p.startsWith('/layers')) {
    forward(req, res);
  } else {
    serveStatic(req, res);
  }
});
server.keepAliveTimeout = 60000;
server.listen(port, '127.0.0.1', () => console.log(`listening ${server.address().port}`));
for (const sig of ['SIGINT', 'SIGTERM']) process.on(sig, () => process.exit(0));
