// Fidelity on the viewer's own pixels (issue #36): the real page (clients/web/index.html +
// viewer.js) in headless Debian Chromium (software GL) against the real mtlod-server. For every
// mesh and orbit camera the page draws the full model (error 0, no budget: the whole MT) and then
// each candidate criteria setting's cut, set through the panel's own controls, so each request is
// the one a user of those settings gets; each picture is scored against the full model's by
// `mtlod-eval score` (core/eval/image_metrics: the foveated error 1 − foveated SSIM of FIDELITY.md).
// Settings are compared at equal bytes: for each of three payload levels (the bytes the default
// criteria send at 1, 0.5 and 0.25 px) every setting's pixel bound is searched until its reply has
// those bytes. Two uses: `pointer` (the viewer, whose mouse is the focus, and mtlod-gaze, whose
// gaze sample is) puts the pointer on the model's image centroid, where the eye is scored;
// `centre` (mtlod-client and mtlod-extract without --focus, which focus the view's centre) keeps
// the pointer at the centre and scores the eye on the centroid. With --agreement-cameras N the same
// cuts of the first N cameras are also made by mtlod-extract and scored by the internal renderer
// (mtlod-eval image), for how well the two studies' pixels agree. The report and csv come from
// viewer_study_report.mjs.
//
// node tests/evaluation/viewer_study.mjs --server build/study/server/mtlod-server \
//     --eval build/study/clients/tools/mtlod-eval [--extract build/study/clients/tools/mtlod-extract] \
//     --mesh ../shared/meshes/lucy-15k.ply ... [--cameras 8] [--uses pointer,centre] \
//     [--agreement-cameras 2] [--settings NAME,...] [--cache-dir build/eval-cache] [--web-root DIR] \
//     --work build/viewer-study [--out tests/evaluation] [--smoke] [--resume]
// node tests/evaluation/viewer_study.mjs --report-only --work build/viewer-study \
//     [--also-work DIR[:LABEL]]... [--note TEXT]... --out tests/evaluation
//
// --smoke: a check, not a study (the ctest entry): two settings, one level, 640×360; exits 1 unless
// every score is finite and the default is within 1.2× of the best setting at its bytes.
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { chromium, chromiumArgs, chromiumOrSkip, parseArgs, root } from '../clients/browser_support.mjs';
import { atBytes, capture, extract, score as scoreFile, startStudyServer } from './study_page.mjs';
import { analyse, writeReport } from './viewer_study_report.mjs';

const smoke = process.argv.includes('--smoke'), reportOnly = process.argv.includes('--report-only');
const args = parseArgs(process.argv.slice(2), reportOnly ? ['work', 'out'] : ['server', 'eval', 'mesh', 'work'],
                       ['--smoke', '--report-only', '--resume']);
const meshes = process.argv.flatMap((a, i) => (a === '--mesh' ? [process.argv[i + 1]] : []));
const cameraCount = Number(args.cameras ?? 8);
const uses = (args.uses ?? 'pointer,centre').split(',');
const agreementCameras = args.extract ? Number(args['agreement-cameras'] ?? 2) : 0;
const cacheDir = args['cache-dir'] ?? path.join(root, 'build/eval-cache');
// The smoke run draws smaller pictures: it checks the machinery, within a test's time.
const size = { width: Number(args.width ?? (smoke ? 640 : 1280)), height: Number(args.height ?? (smoke ? 360 : 720)) };
const kFovDeg = 40;  // mtlod-eval's orbit cameras (clients/tools/eval/support.hpp, kOrbitFovDeg)
const kByteTolerance = 0.03;
fs.mkdirSync(args.work, { recursive: true });
// A setting is the panel's controls (index.html ids); `error` is searched, so left out here.
// The row `viewer default` is the page as it opens: index.html's values, budget included.
const base = { budget: 0, silhouette: false, 'silhouette-distance': 2, 'silhouette-factor': 0.5, focus: true,
               'focus-distance': 80, 'focus-factor': 1, falloff: 'foveal', 'hidden-factor': 16 };
const allSettings = {
  'foveal hidden=16': {},
  'foveal hidden=4': { 'hidden-factor': 4 },
  'foveal hidden=1': { 'hidden-factor': 1 },
  'foveal sil=2/0.5 hidden=16': { silhouette: true },
  'step focus=80/0.25 hidden=16': { falloff: 'step', 'focus-factor': 0.25 },
  'uniform px hidden=16': { falloff: 'step', focus: false },
  'uniform px': { falloff: 'step', focus: false, 'hidden-factor': 1 },
};
const smokeNames = ['foveal hidden=16', 'uniform px hidden=16'];
const chosen = args.settings ? args.settings.split(',') : smoke ? smokeNames : Object.keys(allSettings);
const settings = Object.fromEntries(Object.entries(allSettings).filter(([name]) => chosen.includes(name))
  .map(([name, s]) => [name, { ...base, ...s }]));
const kReference = 'foveal hidden=16';  // sets the byte levels; today's default criteria
const levelsPx = smoke ? [0.25] : [1, 0.5, 0.25];

if (reportOnly) {
  const read = (dir, file) => JSON.parse(fs.readFileSync(path.join(dir, file), 'utf8'));
  const run = read(args.work, 'run.json'), records = read(args.work, 'records.json');
  // Other runs' records join the first's in one report: another use (--uses centre), or a mesh again
  // under another page (DIR:LABEL appends LABEL to its mesh names, so its cases stay apart).
  run.also = process.argv.flatMap((a, i) => (a === '--also-work' ? [process.argv[i + 1]] : [])).map((spec) => {
    const [dir, label] = spec.split(':');
    const also = { ...read(dir, 'run.json'), label };
    records.push(...read(dir, 'records.json').map((r) => (label ? { ...r, mesh: `${r.mesh} ${label}` } : r)));
    run.uses = [...new Set([...run.uses, ...also.uses])];
    return also;
  });
  run.notes = process.argv.flatMap((a, i) => (a === '--note' ? [process.argv[i + 1]] : []));
  report(run, records);
  process.exit(0);
}
const chromiumPath = chromiumOrSkip();
const missing = meshes.filter((m) => !fs.existsSync(m));
if (missing.length) {
  console.log(`skipped: ${missing.join(', ')} missing (../shared/meshes)`);
  process.exit(77);
}

// Camera k of n as mtlod-eval's orbit_camera: azimuth k·360°/n, elevation +25° and −10° in turn, the
// bounding sphere filling 90 % of the field of view.
function orbitCamera(bounds, k, n) {
  const centre = [0, 1, 2].map((a) => (bounds.lo[a] + bounds.hi[a]) / 2);
  const radius = Math.hypot(...[0, 1, 2].map((a) => bounds.hi[a] - bounds.lo[a])) / 2;
  const azimuth = (2 * Math.PI * k) / n, elevation = ((k % 2 === 0 ? 25 : -10) * Math.PI) / 180;
  const distance = radius / Math.sin((kFovDeg / 2) * Math.PI / 180) / 0.9;
  const dir = [Math.cos(elevation) * Math.sin(azimuth), Math.sin(elevation), Math.cos(elevation) * Math.cos(azimuth)];
  return { eye: centre.map((c, a) => c + distance * dir[a]), target: centre, fov: kFovDeg };
}

const score = (reference, candidate, focus) => scoreFile(args.eval, reference, candidate, kFovDeg, focus);

// The setting's cut whose payload is within kByteTolerance of targetBytes, its pixel bound searched
// (bytes ∝ 1/px to start with).
async function cutAtBytes(page, setting, targetBytes, startPx) {
  const found = await atBytes((px) => extract(page, { ...setting, error: px }), targetBytes, startPx,
                              { steps: 7, tolerance: kByteTolerance, slope: { guess: -1, min: -3, max: -0.2 },
                                limit: (px) => Math.min(500, Math.max(0.01, px)) });
  return { px: found.input, reply: found.reply, steps: found.steps };
}

// mtlod-extract's flags for the request the page sends with these controls.
function extractFlags(setting, px, view, focus) {
  const flags = ['--eye', view.eye.join(','), '--target', view.target.join(','), '--up', '0,1,0', '--fov', String(view.fov),
                 '--viewport', `${size.width}x${size.height}`,
                 '--grid', `${Math.min(512, Math.round(size.width / 2))}x${Math.min(512, Math.round(size.height / 2))}`,
                 '--error-px', String(px), '--falloff', setting.falloff, '--hidden-factor', String(setting['hidden-factor'])];
  if (setting.silhouette) flags.push('--silhouette', `${setting['silhouette-distance']},${setting['silhouette-factor']}`);
  if (setting.focus) flags.push('--focus', `${focus[0]},${focus[1]},${setting['focus-distance']},${setting['focus-factor']}`);
  if (setting.budget > 0) flags.push('--budget', String(setting.budget));
  return flags;
}

// The same cut made by mtlod-extract and drawn by the internal renderer (mtlod-eval image).
function internalScore(meshPath, name, setting, px, view, requestFocus, scoreFocus, file) {
  const ply = `${file}.ply`;
  const ex = execFileSync(args.extract, [path.join(cacheDir, `${name}.mt`), ...extractFlags(setting, px, view, requestFocus),
                                         '-o', ply], { encoding: 'utf8' });
  const triangles = Number(/(\d+) triangles/.exec(ex)?.[1]);
  const out = execFileSync(args.eval, ['image', meshPath, ply, '--eye', view.eye.join(','), '--target', view.target.join(','),
                                       '--up', '0,1,0', '--fov', String(view.fov), '--viewport', `${size.width}x${size.height}`,
                                       '--focus', scoreFocus.join(',')], { encoding: 'utf8' });
  fs.rmSync(ply, { force: true });
  const ssim = /SSIM \S+ \(covered pixels \S+, foveated (\S+)\)/.exec(out);
  return { triangles, foveated_error: 1 - Number(ssim[1]) };
}


// The page's controls as index.html sets them: the viewer's defaults.
async function pageDefaults(page) {
  return page.evaluate((ids) => Object.fromEntries(ids.map((id) => {
    const input = document.getElementById(id);
    return [id, input.type === 'checkbox' ? input.checked : input.type === 'number' ? Number(input.value) : input.value];
  })), ['error', ...Object.keys(base)]);
}

// One camera of one mesh: the full model, then every (use, setting, level) at equal bytes.
async function studyCamera(page, mesh, k, records) {
  const view = orbitCamera(mesh.bounds, k, cameraCount);
  const dir = path.join(args.work, mesh.name);
  fs.mkdirSync(dir, { recursive: true });
  await page.evaluate((v) => window.mtlod.setView(v), view);
  const full = await extract(page, { error: 0, budget: 0 });
  const reference = path.join(dir, `cam${k}-full.png`);
  await capture(page, reference);
  const centroid = score(reference, reference).reference_centroid;
  for (const use of uses) {
    const pointer = use === 'pointer' ? centroid : [0.5, 0.5];
    await page.mouse.move(pointer[0] * size.width, pointer[1] * size.height);
    await page.waitForFunction(() => window.mtlod.idle(), null, { timeout: 300_000 });
    const targets = [];
    for (const px of levelsPx) targets.push((await extract(page, { ...settings[kReference], error: px })).bytes);
    const runs = [];
    for (const [name, setting] of Object.entries(settings))
      targets.forEach((bytes, level) => runs.push({ name, setting, level, bytes }));
    if (use === 'pointer') runs.push({ name: 'viewer default', setting: mesh.defaults, level: -1, bytes: 0 });
    for (const run of runs) {
      const cutStarted = Date.now();
      // The previous camera's bound for the same bytes is the best first guess: views of one model
      // at one distance need similar bounds.
      const key = `${use}|${run.name}|${run.level}`;
      const cut = run.level < 0 ? { px: run.setting.error, reply: await extract(page, run.setting), steps: 1 }
                                : await cutAtBytes(page, run.setting, run.bytes, mesh.lastPx.get(key) ?? levelsPx[run.level]);
      mesh.lastPx.set(key, cut.px);
      const file = path.join(dir, `cam${k}-${use}-${run.name.replace(/[^a-z0-9.=]+/gi, '_')}-${run.level}.png`);
      await capture(page, file);
      const s = score(reference, file, centroid);
      const record = { mesh: mesh.name, camera: k, use, setting: run.name, level: run.level,
                       level_px: run.level < 0 ? null : levelsPx[run.level], target_bytes: run.bytes || null,
                       px: cut.px, bytes: cut.reply.bytes, triangles: cut.reply.triangles, steps: cut.steps,
                       full_triangles: full.triangles, focus: centroid, pointer,
                       foveated_error: s.foveated_error, ssim: s.ssim, foveated_mae: s.foveated_mae };
      if (k < agreementCameras) {
        const internal = internalScore(mesh.path, mesh.name, run.setting, cut.px, view, pointer, centroid, file);
        record.internal_foveated_error = internal.foveated_error;
        record.internal_triangles = internal.triangles;
      }
      record.seconds = (Date.now() - cutStarted) / 1000;
      records.push(record);
      if (k > 0) fs.rmSync(file);  // camera 0's pictures stay for figures
    }
  }
}

async function studyMesh(page, httpPort, meshPath, records) {
  const name = path.basename(meshPath, path.extname(meshPath));
  const started = Date.now();
  await page.goto(`http://127.0.0.1:${httpPort}/?model=${encodeURIComponent(name)}`);
  await page.waitForFunction(() => window.mtlod && window.mtlod.meshes > 0 && window.mtlod.idle(), null,
                             { timeout: 600_000 });
  const defaults = await pageDefaults(page);
  // Whole meshes (a delta's bytes are only what changed), and the picture without the page's text.
  await page.evaluate(() => { document.getElementById('delta').checked = false; });
  await page.addStyleTag({ content: '#panel, #overlay { visibility: hidden; }' });
  const bounds = await page.evaluate(() => ({ lo: window.mtlod.bounds.lo.toArray(), hi: window.mtlod.bounds.hi.toArray() }));
  const mesh = { name, path: meshPath, bounds, defaults, lastPx: new Map() };
  for (let k = 0; k < cameraCount; ++k) {
    if (records.some((r) => r.mesh === name && r.camera === k)) continue;  // done before --resume
    await studyCamera(page, mesh, k, records);
    fs.writeFileSync(path.join(args.work, 'records.json'), JSON.stringify(records));
    fs.writeFileSync(path.join(args.work, 'progress.json'), JSON.stringify({ seconds: elapsed() }));
    console.log(`${name} camera ${k}: ${records.length} cuts scored, ${((Date.now() - started) / 1000).toFixed(0)} s`);
  }
  return defaults;
}

// The analysis, printed, and the report when --out is given; also from a finished run's files
// (--report-only --work DIR --out DIR: the report again without running the study).
function report(run, records) {
  const analysis = analyse(records, { levelsPx: run.levelsPx, reference: kReference, uses: run.uses });
  console.log(`${records.length} cuts in ${run.seconds.toFixed(0)} s; default / best at equal bytes: ` +
              `${analysis.defaultRatio.geoMean.toFixed(3)} (worst mesh ${analysis.defaultRatio.worst.toFixed(3)})`);
  if (args.out) writeReport({ ...run, out: args.out, records, analysis });
  return analysis;
}

// --resume: the cameras a stopped run has scored are kept (records.json) and not run again, and the
// time it took counts in the total.
const resume = process.argv.includes('--resume');
const readWork = (file, fallback) => (resume && fs.existsSync(path.join(args.work, file))
  ? JSON.parse(fs.readFileSync(path.join(args.work, file), 'utf8')) : fallback);
const records = readWork('records.json', []);
const startedAt = Date.now(), earlierSeconds = readWork('progress.json', { seconds: 0 }).seconds;
const elapsed = () => earlierSeconds + (Date.now() - startedAt) / 1000;
const { server, httpPort } = await startStudyServer({ binary: args.server, meshes, work: args.work, cacheDir,
                                                     webRoot: args['web-root'] });
const browser = await chromium.launch({
  executablePath: chromiumPath,
  args: chromiumArgs,
});
let defaults = null;
try {
  const page = await browser.newPage({ viewport: size });
  page.on('console', (m) => { if (m.type() === 'error') console.log(`page console: ${m.text()}`); });
  for (const meshPath of meshes) defaults = await studyMesh(page, httpPort, meshPath, records);
} finally {
  await browser.close();
  server.kill('SIGTERM');
}
const command = ['node', path.relative(root, process.argv[1]), ...process.argv.slice(2)].join(' ');
const run = { command, seconds: elapsed(), size, defaults, settings, meshes, cameraCount,
              agreementCameras, levelsPx, uses };
fs.writeFileSync(path.join(args.work, 'run.json'), JSON.stringify(run));
const analysis = report(run, records);
if (smoke) {
  const finite = records.every((r) => Number.isFinite(r.foveated_error) && r.foveated_error >= 0);
  console.log(`${finite ? 'ok  ' : 'FAIL'} every score is finite (${records.length})`);
  const within = analysis.defaultRatio.geoMean <= 1.2;
  console.log(`${within ? 'ok  ' : 'FAIL'} the viewer's default is within 1.2x of the best setting at its bytes`);
  process.exit(finite && within ? 0 : 1);
}
