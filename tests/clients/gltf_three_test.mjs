// .glb files from mtlod-extract, as a viewer reads them: a UV sphere with normals and colours made
// here (normal = the unit position, colour = a function of the position) is built into an MT with
// mtlod-build and extracted with a budget into a Draco-compressed, a meshopt-compressed and a plain
// .glb. All must pass the Khronos validator with no error and no warning (tests/core/gltf_validate.mjs),
// then load in headless Chromium with three.js's GLTFLoader + DRACOLoader + MeshoptDecoder: as many
// triangles and vertices as the file's accessors say (and as mtlod-extract printed), normals and
// colours present and equal to what the sphere's formula gives at each decoded position, placed by
// the file's node (meshopt's quantized positions are dequantized by its translation and scale).
//
// node gltf_three_test.mjs --build BIN --extract BIN --out DIR
import { spawnSync } from 'node:child_process';
import fs from 'node:fs';
import http from 'node:http';
import path from 'node:path';
import { check, chromium, chromiumOrSkip, parseArgs, results, root } from './browser_support.mjs';

const args = parseArgs(process.argv.slice(2), ['build', 'extract', 'out']);
const chromiumPath = chromiumOrSkip();

function run(binary, argv) {
  const r = spawnSync(binary, argv, { encoding: 'utf8' });
  if (r.status !== 0) throw new Error(`${path.basename(binary)} ${argv.join(' ')} failed (${r.status}): ${r.stdout}${r.stderr}`);
  return r.stdout;
}

// The sphere's colour at a point: each channel follows one coordinate from -1 (0) to 1 (255).
const colorAt = (x, y, z) => [x, y, z].map((c) => Math.round(255 * Math.min(1, Math.max(0, (c + 1) / 2))));

// A UV sphere of radius 1 (rings × segments, one vertex per pole), outward triangles, as ASCII PLY.
function writeSphere(file, rings, segments) {
  const vertices = [[0, 0, 1]];
  for (let r = 1; r < rings; ++r) {
    const theta = Math.PI * r / rings;
    for (let s = 0; s < segments; ++s) {
      const phi = 2 * Math.PI * s / segments;
      vertices.push([Math.sin(theta) * Math.cos(phi), Math.sin(theta) * Math.sin(phi), Math.cos(theta)]);
    }
  }
  vertices.push([0, 0, -1]);
  const ring = (r, s) => 1 + (r - 1) * segments + (s % segments);
  const faces = [];
  for (let s = 0; s < segments; ++s) {
    faces.push([0, ring(1, s), ring(1, s + 1)]);
    for (let r = 1; r + 1 < rings; ++r) {
      faces.push([ring(r, s), ring(r + 1, s), ring(r + 1, s + 1)], [ring(r, s), ring(r + 1, s + 1), ring(r, s + 1)]);
    }
    faces.push([ring(rings - 1, s), vertices.length - 1, ring(rings - 1, s + 1)]);
  }
  const lines = ['ply', 'format ascii 1.0', `element vertex ${vertices.length}`, 'property float x', 'property float y',
                 'property float z', 'property float nx', 'property float ny', 'property float nz', 'property uchar red',
                 'property uchar green', 'property uchar blue', `element face ${faces.length}`,
                 'property list uchar int vertex_indices', 'end_header'];
  for (const [x, y, z] of vertices) lines.push(`${x} ${y} ${z} ${x} ${y} ${z} ${colorAt(x, y, z).join(' ')}`);
  for (const f of faces) lines.push(`3 ${f.join(' ')}`);
  fs.writeFileSync(file, `${lines.join('\n')}\n`);
  return faces.length;
}

// What a .glb's JSON says: triangles (indices / 3) and vertices (POSITION count) over its triangle
// primitives, and the attribute names of the first.
function fileCounts(file) {
  const bytes = fs.readFileSync(file);
  if (bytes.toString('latin1', 0, 4) !== 'glTF') throw new Error(`${file} is not a GLB`);
  const jsonLength = bytes.readUInt32LE(12);
  const gltf = JSON.parse(bytes.toString('utf8', 20, 20 + jsonLength));
  let triangles = 0, vertices = 0;
  for (const mesh of gltf.meshes) {
    for (const p of mesh.primitives) {
      if ((p.mode ?? 4) !== 4) throw new Error(`${file}: a primitive is not triangles`);
      triangles += gltf.accessors[p.indices].count / 3;
      vertices += gltf.accessors[p.attributes.POSITION].count;
    }
  }
  return { triangles, vertices, attributes: Object.keys(gltf.meshes[0].primitives[0].attributes).sort(),
           required: (gltf.extensionsRequired ?? []).sort() };
}

const ply = path.join(args.out, 'coloured-sphere.ply'), mt = path.join(args.out, 'coloured-sphere.mt');
const inputTriangles = writeSphere(ply, 48, 96);
run(args.build, [ply, '-o', mt]);
const files = { draco: path.join(args.out, 'sphere-draco.glb'), meshopt: path.join(args.out, 'sphere-meshopt.glb'),
                plain: path.join(args.out, 'sphere-plain.glb') };
const flags = { draco: [], meshopt: ['--codec', 'meshopt'], plain: ['--gltf-compression', 'off'] };
// The extensions each file must require.
const required = { draco: ['KHR_draco_mesh_compression'], meshopt: ['EXT_meshopt_compression', 'KHR_mesh_quantization'],
                   plain: [] };
const printed = {};
for (const [name, file] of Object.entries(files)) {
  const out = run(args.extract, [mt, '--budget', '3000', '-o', file, ...flags[name]]);
  printed[name] = Number(/: (\d+) triangles/.exec(out)?.[1]);
}
check(printed.draco === printed.plain && printed.meshopt === printed.plain && printed.draco > 1000 &&
      printed.draco <= 3000 && printed.draco < inputTriangles,
      `mtlod-extract cut ${printed.draco} (Draco), ${printed.meshopt} (meshopt) and ${printed.plain} (plain) of ${inputTriangles} triangles, within the budget of 3000`);

const validation = spawnSync(process.execPath, [path.join(root, 'tests/core/gltf_validate.mjs'), ...Object.values(files)],
                             { encoding: 'utf8' });
console.log(validation.stdout.trimEnd().replace(/^/gm, '  '));
if (validation.status === 77) {
  console.log('skipped: npm gltf-validator is not installed');
  process.exit(77);
}
check(validation.status === 0, 'the Khronos validator finds no error and no warning in any file');

// The page: three.js from scripts/node_modules, the files, and a function that loads one and reports
// what three.js made of it.
const page = `<!doctype html><html><body>
<script type="importmap">{ "imports": { "three": "/three/build/three.module.js", "three/addons/": "/three/examples/jsm/" } }</script>
<script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { DRACOLoader } from 'three/addons/loaders/DRACOLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
const draco = new DRACOLoader();
draco.setDecoderPath('/three/examples/jsm/libs/draco/');
const loader = new GLTFLoader();
loader.setDRACOLoader(draco);
loader.setMeshoptDecoder(MeshoptDecoder);
window.loadGlb = async (url) => {
  const gltf = await loader.loadAsync(url);
  gltf.scene.updateMatrixWorld(true);
  let triangles = 0, vertices = 0, attributes = null, worstColor = 0, worstNormalDot = 1;
  gltf.scene.traverse((o) => {
    if (!o.isMesh) return;
    const g = o.geometry;
    triangles += (g.index ? g.index.count : g.attributes.position.count) / 3;
    vertices += g.attributes.position.count;
    attributes ??= Object.keys(g.attributes).sort();
    const p = g.attributes.position, n = g.attributes.normal, c = g.attributes.color;
    const at = new THREE.Vector3();
    for (let i = 0; i < p.count; ++i) {
      at.set(p.getX(i), p.getY(i), p.getZ(i)).applyMatrix4(o.matrixWorld);
      const { x, y, z } = at;
      const want = [x, y, z].map((v) => Math.round(255 * Math.min(1, Math.max(0, (v + 1) / 2))));
      if (c) worstColor = Math.max(worstColor, Math.abs(255 * c.getX(i) - want[0]), Math.abs(255 * c.getY(i) - want[1]),
                                   Math.abs(255 * c.getZ(i) - want[2]));
      if (n) {
        const len = Math.hypot(x, y, z);
        worstNormalDot = Math.min(worstNormalDot, (n.getX(i) * x + n.getY(i) * y + n.getZ(i) * z) / len);
      }
    }
  });
  return { triangles, vertices, attributes, worstColor, worstNormalDot };
};
window.ready = true;
</script></body></html>`;

const served = Object.fromEntries(Object.values(files).map((file) => [`/${path.basename(file)}`, file]));
const types = { '.js': 'text/javascript', '.wasm': 'application/wasm', '.glb': 'model/gltf-binary' };
const server = http.createServer((req, res) => {
  const url = new URL(req.url, 'http://localhost').pathname;
  let file = served[url];
  if (!file && url.startsWith('/three/')) {
    const three = path.join(root, 'scripts/node_modules/three');
    file = path.join(three, path.normalize(url.slice('/three/'.length)));
    if (!file.startsWith(three)) file = undefined;
  }
  if (url === '/favicon.ico') {
    res.writeHead(204);
    res.end();
  } else if (url === '/') {
    res.writeHead(200, { 'content-type': 'text/html' });
    res.end(page);
  } else if (file && fs.existsSync(file)) {
    res.writeHead(200, { 'content-type': types[path.extname(file)] ?? 'application/octet-stream' });
    res.end(fs.readFileSync(file));
  } else {
    res.writeHead(404);
    res.end();
  }
});
await new Promise((resolve) => server.listen(0, '127.0.0.1', resolve));

let browser = null;
const deadline = setTimeout(() => {
  console.log('FAIL the test did not finish within 90 s');
  process.exit(1);
}, 90_000);
try {
  browser = await chromium.launch({
    executablePath: chromiumPath,
    args: ['--no-sandbox', '--disable-gpu', '--no-first-run', '--disable-background-networking',
           '--disable-component-update', '--disable-sync'],
  });
  const tab = await browser.newPage();
  tab.on('console', (m) => { if (m.type() === 'error') console.log(`page console: ${m.text()}`); });
  tab.on('pageerror', (e) => console.log(`page error: ${e.message}`));
  await tab.goto(`http://127.0.0.1:${server.address().port}/`);
  await tab.waitForFunction(() => window.ready === true, null, { timeout: 30_000 });
  for (const [name, file] of Object.entries(files)) {
    const want = fileCounts(file);
    const got = await tab.evaluate((url) => window.loadGlb(url), `/${path.basename(file)}`);
    check(JSON.stringify(want.required) === JSON.stringify(required[name]),
          `${name}: the file requires [${want.required}], expected [${required[name]}]`);
    check(got.triangles === want.triangles && got.triangles === printed[name],
          `${name}: three.js shows ${got.triangles} triangles, the file's indices say ${want.triangles}, mtlod-extract ${printed[name]}`);
    check(got.vertices === want.vertices, `${name}: three.js has ${got.vertices} vertices, the file's POSITION ${want.vertices}`);
    check(JSON.stringify(want.attributes) === JSON.stringify(['COLOR_0', 'NORMAL', 'POSITION']) &&
          JSON.stringify(got.attributes) === JSON.stringify(['color', 'normal', 'position']),
          `${name}: attributes ${want.attributes} in the file, ${got.attributes} in three.js`);
    // Colours: the formula at the decoded position, within one unit (14-bit positions move a
    // coordinate by up to 1.2e-4, a channel by 0.02, and the rounding may fall either side).
    check(got.worstColor <= 1.02, `${name}: every colour matches its position (worst ${got.worstColor.toFixed(3)} of 255)`);
    // Normals: the unit position, within the codecs' 10-bit quantization (float32 exactly for plain).
    check(got.worstNormalDot > 0.999, `${name}: every normal points along its position (worst cosine ${got.worstNormalDot.toFixed(6)})`);
  }
} catch (error) {
  console.log(`FAIL ${error.stack ?? error}`);
  results.failures += 1;
} finally {
  if (browser) await browser.close();
  server.close();
  clearTimeout(deadline);
}
process.exit(results.failures ? 1 : 0);
