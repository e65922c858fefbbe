// A scene on the viewer's own pixels (issue #40): the real page (clients/web/index.html + viewer.js)
// in headless Debian Chromium (software GL) against the real mtlod-server, showing its built-in room
// (?scene=room: 16 instances of the server's first four models). For every orbit camera the page
// draws the room at full resolution (error 0, no budget), then each case twice at equal bytes:
// - `scene`: one scene request (the panel's "scene requests: one for the scene"): one grid for the
//   whole picture, silhouettes where instances meet, what one hides of another coarse, one budget
//   spent worst-first across the instances;
// - `per instance`: what a client without scene requests does ("one per instance"): one extract per
//   instance at a quarter of the scene's pixel bound, the budget split evenly, that budget searched
//   until the replies together have the scene's bytes (within 3 %).
// Both pictures are scored against the full room by `mtlod-eval score` (the foveated error
// 1 − foveated SSIM of FIDELITY.md, the eye at the pointer, which is the focus, at the centre).
//
// node tests/evaluation/scene_study.mjs --server build/release/server/mtlod-server \
//     --eval build/release/clients/tools/mtlod-eval --mesh M1 --mesh M2 --mesh M3 --mesh M4 \
//     --work build/scene-study [--cameras 8] [--cache-dir build/eval-cache] [--out tests/evaluation] [--smoke]
//
// --smoke: a check, not a study (the ctest entry): 2 cameras, 640×360, the cases where the bound binds
// and one budget; exits 1 unless every score is finite, both pictures of a case are within 3 % of the
// same bytes, no instance of the scene request is finer than its own request with the same criteria
// where the bound binds, and the scene request is coarser than those on some camera.
import fs from 'node:fs';
import path from 'node:path';
import { chromium, chromiumArgs, chromiumOrSkip, parseArgs, root } from '../clients/browser_support.mjs';
import { atBytes, capture, extract, score, startStudyServer } from './study_page.mjs';

const smoke = process.argv.includes('--smoke');
const args = parseArgs(process.argv.slice(2), ['server', 'eval', 'mesh', 'work'], ['--smoke']);
const meshes = process.argv.flatMap((a, i) => (a === '--mesh' ? [process.argv[i + 1]] : []));
const cameraCount = Number(args.cameras ?? (smoke ? 2 : 8));
const cacheDir = args['cache-dir'] ?? path.join(root, 'build/eval-cache');
const size = { width: smoke ? 640 : 1280, height: smoke ? 360 : 720 };
const kFovDeg = 40;
const kByteTolerance = 0.03;
// The panel's controls of every request but the error, budget and scene requests: the viewer's
// defaults (foveal falloff from the pointer, hidden surfaces ×16), whole meshes, Draco.
const base = { delta: false, silhouette: false, focus: true, 'focus-distance': 80, 'focus-factor': 1, falloff: 'foveal',
               'hidden-factor': 16, codec: 'draco' };
// bound: the pixel bound binds (no budget); budget N: the budget binds (a bound 4 times finer).
const allCases = [
  { name: 'bound 0.5 px', error: 0.5, budget: 0 },
  { name: 'budget 20k', error: 0.125, budget: 20000 },
  { name: 'budget 5k', error: 0.125, budget: 5000 },
];
const cases = smoke ? allCases.slice(0, 2) : allCases;
fs.mkdirSync(args.work, { recursive: true });

const chromiumPath = chromiumOrSkip();
const missing = meshes.filter((m) => !fs.existsSync(m));
if (missing.length || meshes.length < 2) {
  console.log(missing.length ? `skipped: ${missing.join(', ')} missing (../shared/meshes)` : 'give at least two --mesh');
  process.exit(missing.length ? 77 : 2);
}

// Camera k of n around the room's box: azimuth k·360°/n from the front, raised 25° and 10° in turn
// (rows behind partly showing over rows in front), the box's sphere filling the view.
function orbitCamera(lo, hi, k, n) {
  const centre = [0, 1, 2].map((a) => (lo[a] + hi[a]) / 2);
  const radius = Math.hypot(...[0, 1, 2].map((a) => hi[a] - lo[a])) / 2;
  const azimuth = (2 * Math.PI * k) / n, elevation = ((k % 2 === 0 ? 25 : 10) * Math.PI) / 180;
  const distance = radius / Math.sin((kFovDeg / 2) * Math.PI / 180) * 0.8;
  const dir = [Math.cos(elevation) * Math.sin(azimuth), Math.sin(elevation), Math.cos(elevation) * Math.cos(azimuth)];
  return { eye: centre.map((c, a) => c + distance * dir[a]), target: centre, fov: kFovDeg };
}

// The per-instance requests whose replies together have targetBytes, the budget searched from the
// scene's triangle count.
async function perInstanceAtBytes(page, error, targetBytes, startBudget, instances) {
  const request = (budget) => extract(page, { 'scene-requests': 'instances', error, budget });
  const found = await atBytes(request, targetBytes, startBudget,
                              { steps: 8, tolerance: kByteTolerance, slope: { guess: 1, min: 0.2, max: 3 },
                                limit: (budget) => Math.max(instances, Math.round(budget)), same: (a, b) => a === b });
  return { budget: found.input, reply: found.reply, steps: found.steps };
}

async function studyCamera(page, box, k, records) {
  const view = orbitCamera(box.lo, box.hi, k, cameraCount);
  await page.evaluate((v) => window.mtlod.setView(v), view);
  const full = await extract(page, { 'scene-requests': 'scene', error: 0, budget: 0 });
  const reference = path.join(args.work, `cam${k}-full.png`);
  await capture(page, reference);
  const focus = [0.5, 0.5];
  for (const c of cases) {
    const started = Date.now();
    const scene = await extract(page, { 'scene-requests': 'scene', error: c.error, budget: c.budget });
    const sceneFile = path.join(args.work, `cam${k}-${c.name.replace(/\W+/g, '_')}-scene.png`);
    await capture(page, sceneFile);
    // The same criteria per instance: what seeing the whole picture saves (nothing can be finer in
    // the scene request: a vertex is hidden by more surface, and no other criterion looks past its
    // instance while the silhouette band is off).
    const same = await extract(page, { 'scene-requests': 'instances', error: c.error, budget: c.budget });
    const apart = await perInstanceAtBytes(page, c.error / 4, scene.bytes, Math.max(scene.triangles, 16),
                                           scene.instances.length);
    const apartFile = path.join(args.work, `cam${k}-${c.name.replace(/\W+/g, '_')}-per_instance.png`);
    await capture(page, apartFile);
    const s = score(args.eval, reference, sceneFile, kFovDeg, focus), p = score(args.eval, reference, apartFile, kFovDeg, focus);
    records.push({ camera: k, case: c.name, full_triangles: full.triangles, full_bytes: full.bytes,
                   scene: { triangles: scene.triangles, bytes: scene.bytes, foveated_error: s.foveated_error,
                            within_budget: scene.within_budget ?? null,
                            instance_triangles: scene.instances.map((i) => i.triangles) },
                   same_criteria: { triangles: same.triangles, bytes: same.bytes,
                                    instance_triangles: same.instances.map((i) => i.triangles) },
                   per_instance: { budget: apart.budget, share: Math.floor(apart.budget / scene.instances.length),
                                   triangles: apart.reply.triangles, bytes: apart.reply.bytes,
                                   foveated_error: p.foveated_error, steps: apart.steps },
                   gain: p.foveated_error / s.foveated_error, seconds: (Date.now() - started) / 1000 });
    if (k > 0) for (const file of [sceneFile, apartFile]) fs.rmSync(file);  // camera 0's stay for figures
  }
  if (k > 0) fs.rmSync(reference);
}

const geoMean = (values) => Math.exp(values.reduce((sum, v) => sum + Math.log(v), 0) / values.length);
const fmt = (n) => n.toLocaleString('en-US');

function summarise(records) {
  return cases.map((c) => {
    const rows = records.filter((r) => r.case === c.name);
    return { case: c.name, cameras: rows.length, gain: geoMean(rows.map((r) => r.gain)),
             wins: rows.filter((r) => r.gain > 1).length,
             worst: Math.min(...rows.map((r) => r.gain)), best: Math.max(...rows.map((r) => r.gain)),
             scene_triangles: geoMean(rows.map((r) => r.scene.triangles)),
             same_triangles: geoMean(rows.map((r) => r.same_criteria.triangles)),
             apart_triangles: geoMean(rows.map((r) => r.per_instance.triangles)),
             bytes: geoMean(rows.map((r) => r.scene.bytes)),
             scene_error: geoMean(rows.map((r) => r.scene.foveated_error)),
             apart_error: geoMean(rows.map((r) => r.per_instance.foveated_error)) };
  });
}

function writeReport(run, records, summary) {
  const lines = [
    '# A scene on the viewer\'s own pixels', '',
    `Generated by \`${run.command}\` in ${run.seconds.toFixed(0)} s. Do not edit by hand.`, '',
    `The viewer's room (\`?scene=room\`: ${run.instances} instances of ${run.models.join(', ')}), ${run.size.width}×${run.size.height}, ` +
    `${cameraCount} cameras around it, the pointer (the focus) at the centre. Each case is drawn twice by the page at equal ` +
    'bytes (Draco, whole meshes): one scene request, and one request per instance (a quarter of the pixel bound, the ' +
    'budget split evenly and searched until the replies have the scene\'s bytes). The error is FIDELITY.md\'s foveated ' +
    'error (1 − foveated SSIM) against the room at full resolution; gain = per-instance error / scene error ' +
    '(above 1: the scene request is closer).', '',
    '| case | cameras | per instance, same criteria: triangles | bytes | scene: triangles, error | per instance at equal bytes: triangles, error | gain (geo-mean) | scene closer | range |',
    '| --- | ---: | ---: | ---: | --- | --- | ---: | ---: | --- |',
    ...summary.map((s) => `| ${s.case} | ${s.cameras} | ${fmt(Math.round(s.same_triangles))} | ${fmt(Math.round(s.bytes))} | ${fmt(Math.round(s.scene_triangles))}, ` +
                          `${s.scene_error.toFixed(3)} | ${fmt(Math.round(s.apart_triangles))}, ${s.apart_error.toFixed(3)} | ` +
                          `**${s.gain.toFixed(2)}×** | ${s.wins} of ${s.cameras} | ${s.worst.toFixed(2)}–${s.best.toFixed(2)} |`),
    '', '## Per camera', '',
    '| camera | case | scene triangles | bytes | scene error | per-instance share | triangles | bytes | error | gain |',
    '| ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |',
    ...records.map((r) => `| ${r.camera} | ${r.case} | ${fmt(r.scene.triangles)} | ${fmt(r.scene.bytes)} | ` +
                          `${r.scene.foveated_error.toFixed(4)} | ${fmt(r.per_instance.share)} | ${fmt(r.per_instance.triangles)} | ` +
                          `${fmt(r.per_instance.bytes)} | ${r.per_instance.foveated_error.toFixed(4)} | ${r.gain.toFixed(3)} |`),
    '',
  ];
  fs.writeFileSync(path.join(args.out, 'SCENE.md'), lines.join('\n'));
  const csv = ['camera,case,scene_triangles,scene_bytes,scene_error,share,apart_triangles,apart_bytes,apart_error,gain',
               ...records.map((r) => [r.camera, r.case, r.scene.triangles, r.scene.bytes, r.scene.foveated_error.toFixed(5),
                                      r.per_instance.share, r.per_instance.triangles, r.per_instance.bytes,
                                      r.per_instance.foveated_error.toFixed(5), r.gain.toFixed(4)].join(','))];
  fs.writeFileSync(path.join(args.out, 'scene.csv'), `${csv.join('\n')}\n`);
}

const startedAt = Date.now();
const { server, httpPort } = await startStudyServer({ binary: args.server, meshes, work: args.work, cacheDir });
const browser = await chromium.launch({ executablePath: chromiumPath, args: chromiumArgs });
const records = [];
let room = null;
try {
  const page = await browser.newPage({ viewport: size });
  page.on('console', (m) => { if (m.type() === 'error') console.log(`page console: ${m.text()}`); });
  await page.goto(`http://127.0.0.1:${httpPort}/?scene=room`);
  await page.waitForFunction(() => window.mtlod && window.mtlod.meshes > 0 && window.mtlod.idle(), null, { timeout: 600_000 });
  await page.addStyleTag({ content: '#panel, #overlay { visibility: hidden; }' });
  await extract(page, base);
  room = await page.evaluate(() => ({ lo: window.mtlod.scene.lo.toArray(), hi: window.mtlod.scene.hi.toArray(),
                                      instances: window.mtlod.scene.instances.length,
                                      models: [...new Set(window.mtlod.scene.instances.map((i) => i.model))] }));
  for (let k = 0; k < cameraCount; ++k) {
    await studyCamera(page, room, k, records);
    fs.writeFileSync(path.join(args.work, 'records.json'), JSON.stringify(records));
    console.log(`camera ${k}: ${records.length} cases, ${((Date.now() - startedAt) / 1000).toFixed(0)} s`);
  }
} finally {
  await browser.close();
  server.kill('SIGTERM');
}
const summary = summarise(records);
for (const s of summary) {
  console.log(`${s.case}: gain ${s.gain.toFixed(3)} (${s.wins} of ${s.cameras} cameras, ${s.worst.toFixed(3)}–${s.best.toFixed(3)}), ` +
              `scene ${Math.round(s.scene_triangles)} triangles, per instance ${Math.round(s.apart_triangles)}`);
}
const command = ['node', path.relative(root, process.argv[1]), ...process.argv.slice(2)].join(' ');
const run = { command, seconds: (Date.now() - startedAt) / 1000, size, instances: room.instances, models: room.models };
if (args.out) writeReport(run, records, summary);
if (smoke) {
  let ok = true;
  const say = (pass, text) => { console.log(`${pass ? 'ok  ' : 'FAIL'} ${text}`); ok &&= pass; };
  say(records.every((r) => Number.isFinite(r.scene.foveated_error) && Number.isFinite(r.per_instance.foveated_error)),
      `every score is finite (${records.length} cases)`);
  say(records.every((r) => Math.abs(r.per_instance.bytes / r.scene.bytes - 1) < kByteTolerance),
      'both pictures of every case are within 3 % of the same bytes');
  say(records.filter((r) => r.case === cases[0].name)
    .every((r) => r.scene.instance_triangles.every((t, i) => t <= r.same_criteria.instance_triangles[i])),
      'where the bound binds, no instance of the scene request is finer than its own request with the same criteria');
  say(records.some((r) => r.scene.triangles < r.same_criteria.triangles),
      'the scene request coarsens what one instance hides of another on some camera');
  process.exit(ok ? 0 : 1);
}
