// Client decode time in three.js: payloads written by mtlod-extract (.drc, .mopt) decoded in headless
// Chromium the way the viewer decodes them (clients/web/codecs.js: three.js's DRACOLoader, whose wasm
// decoder from three/examples/jsm/libs/draco/ runs in a worker, and MeshoptDecoder), each payload `--runs`
// samples after `--warmup` decodes, one decode at a time (a sample of small payloads decodes several times
// over); the median is reported. For .mopt payloads also
// MeshoptDecoder's stream calls alone (decodeVertexBuffer with the OCTAHEDRAL filter for normals,
// decodeIndexBuffer), without the container's checks and the conversion to float attributes that the
// viewer's geometry needs (DRACOLoader's geometry has them too). No server and no GL: the page and its
// files are served to Chromium by this script. Prints a Markdown table (BENCHMARKS.md, "Client decode in
// three.js").
//
// node tests/bench/decode_three.mjs [--runs N] [--warmup N] [--json FILE] PAYLOAD.drc|PAYLOAD.mopt ...
import fs from 'node:fs';
import path from 'node:path';
import { chromium, chromiumArgs, chromiumOrSkip, root } from '../clients/browser_support.mjs';

const argv = process.argv.slice(2);
const option = (name, fallback) => {
  const at = argv.indexOf(`--${name}`);
  if (at < 0) return fallback;
  const [value] = argv.splice(at, 2).slice(1);
  return value;
};
const runs = Number(option('runs', 51));
const warmup = Number(option('warmup', 10));
const jsonOut = option('json', null);
const payloads = argv;
if (payloads.length === 0 || !(runs > 0) || !(warmup >= 0) || payloads.some((p) => !/\.(drc|mopt)$/.test(p))) {
  console.error('usage: node tests/bench/decode_three.mjs [--runs N] [--warmup N] [--json FILE] PAYLOAD.drc|PAYLOAD.mopt ...');
  process.exit(2);
}
const chromiumPath = chromiumOrSkip();

// The page's origin exists only inside this browser: every request is answered from the disk here.
const origin = 'http://decode-bench.invalid';
const page = `<!doctype html><meta charset="utf-8">
<script type="importmap">{ "imports": { "three": "/three/build/three.module.js", "three/addons/": "/three/examples/jsm/" } }</script>
<script type="module">
  import { decodePayload } from '/web/codecs.js';
  import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';

  // MeshoptDecoder's calls alone on the MOPT container's streams (the header is trusted here).
  function meshoptStreams(bytes) {
    const data = new Uint8Array(bytes), view = new DataView(bytes);
    const flags = data[5], vertices = view.getUint32(8, true), triangles = view.getUint32(12, true);
    let at = 32;
    const next = () => { const n = view.getUint32(at, true); at += 4 + n; return data.subarray(at - n, at); };
    MeshoptDecoder.decodeVertexBuffer(new Uint8Array(8 * vertices), vertices, 8, next());
    if (flags & 1) {
      const stride = flags & 4 ? 8 : 4;
      MeshoptDecoder.decodeVertexBuffer(new Uint8Array(stride * vertices), vertices, stride, next(), 'OCTAHEDRAL');
    }
    if (flags & 2) MeshoptDecoder.decodeVertexBuffer(new Uint8Array(4 * vertices), vertices, 4, next());
    MeshoptDecoder.decodeIndexBuffer(new Uint8Array(12 * triangles), 3 * triangles, 4, next());
  }

  const median = (values) => values.sort((a, b) => a - b)[values.length >> 1];

  // Times \`decode\` (of a fresh copy of the bytes: Draco's is transferred to its worker), one decode at
  // a time: warmup decodes, then runs samples of as many decodes as take about 5 ms by the warm-up's
  // mean (the page's clock ticks in 0.1 ms), each sample's time divided by its decodes.
  async function time(bytes, warmup, runs, decode) {
    const copies = (n) => Array.from({ length: n }, () => bytes.slice(0));
    const started = performance.now();
    for (const copy of copies(warmup)) await decode(copy);
    const batch = Math.max(1, Math.round(5 / Math.max(0.01, (performance.now() - started) / Math.max(1, warmup))));
    const times = [];
    for (let i = 0; i < runs; ++i) {
      const batchCopies = copies(batch);
      const start = performance.now();
      for (const copy of batchCopies) await decode(copy);
      times.push((performance.now() - start) / batch);
    }
    return { median: median(times), batch };
  }

  window.bench = async (url, codec, warmup, runs) => {
    await MeshoptDecoder.ready;
    const bytes = await (await fetch(url)).arrayBuffer();
    const geometry = await decodePayload(codec, bytes.slice(0));
    const out = { bytes: bytes.byteLength, triangles: geometry.index.count / 3, vertices: geometry.getAttribute('position').count,
                  normals: geometry.getAttribute('normal') !== undefined, colors: geometry.getAttribute('color') !== undefined };
    geometry.dispose();
    out.decode = await time(bytes, warmup, runs, async (copy) => (await decodePayload(codec, copy)).dispose());
    if (codec === 'meshopt') out.streams = await time(bytes, warmup, runs, async (copy) => meshoptStreams(copy));
    return out;
  };
  window.benchReady = true;
</script>`;

const files = {
  '/three/': path.join(root, 'scripts/node_modules/three'),
  '/web/': path.join(root, 'clients/web'),
};
const types = { '.js': 'text/javascript', '.wasm': 'application/wasm', '.html': 'text/html' };

const browser = await chromium.launch({ executablePath: chromiumPath, args: chromiumArgs });
const results = [];
try {
  const context = await browser.newContext();
  await context.route(`${origin}/**`, async (route) => {
    const url = new URL(route.request().url());
    if (url.pathname === '/') return route.fulfill({ contentType: 'text/html', body: page });
    const payload = url.pathname.match(/^\/payload\/(\d+)$/);
    if (payload) return route.fulfill({ contentType: 'application/octet-stream', body: fs.readFileSync(payloads[Number(payload[1])]) });
    for (const [prefix, dir] of Object.entries(files)) {
      const file = path.join(dir, url.pathname.slice(prefix.length));
      if (url.pathname.startsWith(prefix) && file.startsWith(dir) && fs.existsSync(file)) {
        return route.fulfill({ contentType: types[path.extname(file)] ?? 'application/octet-stream', body: fs.readFileSync(file) });
      }
    }
    return route.fulfill({ status: 404, body: `not found: ${url.pathname}` });
  });
  const tab = await context.newPage();
  tab.on('pageerror', (e) => console.error(`page error: ${e.message}`));
  await tab.goto(`${origin}/`);
  await tab.waitForFunction(() => window.benchReady === true);
  const version = await tab.evaluate(async () => (await import('three')).REVISION);
  for (const [i, file] of payloads.entries()) {
    const codec = file.endsWith('.mopt') ? 'meshopt' : 'draco';
    const r = await tab.evaluate(([url, c, w, n]) => window.bench(url, c, w, n), [`/payload/${i}`, codec, warmup, runs]);
    results.push({ file: path.basename(file), codec, ...r });
  }
  console.log(`three.js r${version}, medians of ${runs} samples after ${warmup} warm-up decodes\n`);
  console.log('| payload | triangles | bytes/triangle | decode ms as the viewer decodes (DRACOLoader / codecs.js) | MeshoptDecoder streams alone ms |');
  console.log('| --- | ---: | ---: | ---: | ---: |');
  for (const r of results) {
    console.log(`| ${r.file} (${r.codec}${r.normals ? ', normals' : ''}${r.colors ? ', colours' : ''}) | ${r.triangles} | ` +
                `${(r.bytes / r.triangles).toFixed(2)} | ${r.decode.median.toFixed(2)} | ${r.streams ? r.streams.median.toFixed(2) : '–'} |`);
  }
  if (jsonOut) fs.writeFileSync(jsonOut, `${JSON.stringify({ three: version, runs, warmup, results }, null, 2)}\n`);
} finally {
  await browser.close();
}
