// Browser test of the viewer's codecs: one mtlod-server, two pages in headless Debian Chromium at the
// same view, one on Draco payloads (the default) and one on meshopt ones (?codec=meshopt), driven alike.
// On the meshopt page, as read off the WebSocket: the extracts ask for meshopt, the replies carry MOPT
// payloads, the painted mesh has the reply's triangle count, a gaze comes as a delta that applies (the kept
// mesh holds the server's cut), the mesh has the server's normals and is smooth-shaded, and colours come
// through deltas. Against the Draco page: the same cut, triangle by triangle (ids, corners on the
// position grid in the same winding, normals, colours), and screenshots whose pixels agree. A damaged
// payload, a delta's and then a whole mesh's, shows an error and the page goes on. The panel's codec
// choice switches the Draco page to meshopt. Saves the screenshots into --out.
//
// node viewer_codecs_test.mjs --server BIN --mesh bunny.ply [--painted painted.ply] --out DIR
import fs from 'node:fs';
import path from 'node:path';
import { check, chromium, chromiumArgs, chromiumOrSkip, comparePictures, finish, parseArgs, results, startServer } from './browser_support.mjs';

const args = parseArgs(process.argv.slice(2), ['server', 'mesh', 'out']);
const chromiumPath = chromiumOrSkip();
if (!fs.existsSync(args.mesh)) {
  console.log(`skipped: ${args.mesh} is missing (scripts/prepare-models.sh writes it)`);
  process.exit(77);
}

const size = { width: 800, height: 600 };
const kPositionBits = 14;            // the viewer's (and the protocol's default) draco.position_bits
const kBackground = [0x20, 0x24, 0x28];  // viewer.js's scene.background
// Screenshot tolerance. The two codecs put positions on the same grid points and quantize normals alike
// (octahedral, 10 bits; they agree within 0.01°), and the same software GL draws both pages: the pictures
// come out the same but for a stray pixel. A decode that is off (a wrong winding, which two-sided lighting
// turns into the far side's shading; normals not unfolded; positions a few steps away) changes many of
// the model's pixels by far more.
const kPixelThreshold = 8;           // a pixel differs when a channel differs by more than this
const kMaxDifferingShare = 0.002;    // of the model's pixels
const kMaxMeanDifference = 0.2;      // over the picture's pixels and channels, 0..255

const deadline = setTimeout(() => {
  console.log('FAIL the test did not finish within 200 s');
  process.exit(1);
}, 200_000);

let server = null, browser = null;

// A viewer page asking for `codec`, its WebSocket routed through here: the requests it sends and the
// mesh replies it receives are recorded, and `damage` (a queue of functions of a binary frame's Buffer
// and JSON) may change the next binary mesh frames before the page sees them.
async function openViewer(codec, origin) {
  const page = await browser.newPage({ viewport: size });
  const viewer = { codec, page, sent: [], replies: [], damage: [] };
  page.on('console', (m) => { if (m.type() === 'error') console.log(`${codec} page console: ${m.text()}`); });
  page.on('pageerror', (e) => console.log(`${codec} page error: ${e.message}`));
  await page.routeWebSocket(/\/ws(\?|$)/, (ws) => {
    const upstream = ws.connectToServer();
    ws.onMessage((message) => {
      viewer.sent.push(JSON.parse(message.toString()));
      upstream.send(message);
    });
    upstream.onMessage((message) => {
      if (typeof message === 'string') {
        const json = JSON.parse(message);
        if (json.type === 'mesh') viewer.replies.push({ json, payload: Buffer.alloc(0) });
        ws.send(message);
        return;
      }
      const jsonBytes = message.readUInt32LE(0), payloadBytes = message.readUInt32LE(4);
      const json = JSON.parse(message.subarray(8, 8 + jsonBytes).toString('utf8'));
      const payload = message.subarray(8 + jsonBytes, 8 + jsonBytes + payloadBytes);
      if (json.type === 'mesh') {
        viewer.replies.push({ json, payload, frameBytes: message.length });
        if (viewer.damage.length > 0) message = viewer.damage.shift()(Buffer.from(message), json, 8 + jsonBytes);
      }
      ws.send(message);
    });
  });
  await page.goto(`${origin}/?codec=${codec}`);
  return viewer;
}

const settled = (viewer, after = 0) => viewer.page.waitForFunction(
  (n) => window.mtlod && window.mtlod.meshes > n && window.mtlod.idle(), after, { timeout: 60_000 });
const shown = (viewer) => viewer.page.evaluate(() => ({
  reply: window.mtlod.lastReply, triangles: Number(document.getElementById('triangles').textContent),
  normals: window.mtlod.lastReplyHadNormals, colours: window.mtlod.lastReplyHadColors, flat: window.mtlod.flatShading,
  errors: [...window.mtlod.errors], meshes: window.mtlod.meshes, status: document.getElementById('status').textContent,
}));
const replyTo = (viewer, id) => viewer.replies.find((r) => r.json.id === id);

// The kept mesh of a page (viewer.js, state.keptMesh), its typed arrays carried as base64.
async function keptMesh(viewer) {
  const encoded = await viewer.page.evaluate(() => {
    const base64 = (a) => {
      if (!a) return null;
      const bytes = new Uint8Array(a.buffer, a.byteOffset, a.byteLength);
      let text = '';
      for (let i = 0; i < bytes.length; i += 0x8000) text += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
      return btoa(text);
    };
    const k = window.mtlod.keptMesh();
    return Object.fromEntries(Object.entries(k).map(([key, value]) => [key, base64(value)]));
  });
  const decode = (text, Type) => {
    if (text === null) return null;
    const bytes = Buffer.from(text, 'base64');
    return new Type(bytes.buffer, bytes.byteOffset, bytes.byteLength / Type.BYTES_PER_ELEMENT);
  };
  return { ids: decode(encoded.ids, Uint32Array), positions: decode(encoded.positions, Float32Array),
           normals: decode(encoded.normals, Float32Array), colors: decode(encoded.colors, Float32Array) };
}

// Draco's kept mesh against meshopt's, triangle by triangle (by id): the corners may start at another
// corner (meshoptimizer's index codec rotates triangles) but keep their winding. Returns, over each
// triangle's best rotation, the largest difference of a coordinate in grid steps, the corners with a
// coordinate more than a tenth of a step apart, the largest normal angle in degrees and the largest
// colour difference.
function compareKept(draco, meshopt, step) {
  const slot = new Map();
  meshopt.ids.forEach((id, i) => slot.set(id, i));
  const out = { missing: 0, maxSteps: 0, offCorners: 0, corners: 0, maxDegrees: 0, maxColour: 0 };
  const corner = (array, t, k, r) => array.subarray(9 * t + 3 * ((k + r) % 3), 9 * t + 3 * ((k + r) % 3) + 3);
  for (let t = 0; t < draco.ids.length; ++t) {
    const u = slot.get(draco.ids[t]);
    if (u === undefined) {
      out.missing += 1;
      continue;
    }
    let best = null;
    for (let r = 0; r < 3; ++r) {
      let distance = 0;
      for (let k = 0; k < 3; ++k) {
        const a = corner(draco.positions, t, k, 0), b = corner(meshopt.positions, u, k, r);
        distance = Math.max(distance, Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]));
      }
      if (!best || distance < best.distance) best = { distance, r };
    }
    for (let k = 0; k < 3; ++k) {
      const a = corner(draco.positions, t, k, 0), b = corner(meshopt.positions, u, k, best.r);
      const apart = Math.max(Math.abs(a[0] - b[0]), Math.abs(a[1] - b[1]), Math.abs(a[2] - b[2])) / step;
      out.maxSteps = Math.max(out.maxSteps, apart);
      if (apart > 0.1) out.offCorners += 1;
      out.corners += 1;
      if (draco.normals && meshopt.normals) {
        const n = corner(draco.normals, t, k, 0), m = corner(meshopt.normals, u, k, best.r);
        const cosine = (n[0] * m[0] + n[1] * m[1] + n[2] * m[2]) / (Math.hypot(...n) * Math.hypot(...m));
        out.maxDegrees = Math.max(out.maxDegrees, Math.acos(Math.min(1, cosine)) * 180 / Math.PI);
      }
      if (draco.colors && meshopt.colors) {
        const c = corner(draco.colors, t, k, 0), d = corner(meshopt.colors, u, k, best.r);
        for (let i = 0; i < 3; ++i) out.maxColour = Math.max(out.maxColour, Math.abs(c[i] - d[i]));
      }
    }
  }
  return out;
}

async function compareCodecs(draco, meshopt, what) {
  const [d, m] = [await shown(draco), await shown(meshopt)];
  check(d.reply.triangles === m.reply.triangles && d.triangles === m.triangles,
        `${what}: the Draco and meshopt pages show the same cut (${d.triangles} and ${m.triangles} triangles; the server's ${d.reply.triangles} and ${m.reply.triangles})`);
  const bounds = await draco.page.evaluate(() => window.mtlod.bounds);
  const step = Math.max(bounds.hi.x - bounds.lo.x, bounds.hi.y - bounds.lo.y, bounds.hi.z - bounds.lo.z) / (2 ** kPositionBits - 1);
  const [keptDraco, keptMeshopt] = [await keptMesh(draco), await keptMesh(meshopt)];
  const c = compareKept(keptDraco, keptMeshopt, step);
  check(keptDraco.ids.length === keptMeshopt.ids.length && c.missing === 0,
        `${what}: the kept meshes hold the same triangles (${keptDraco.ids.length} and ${keptMeshopt.ids.length}, ${c.missing} of Draco's missing in meshopt's)`);
  // Both encoders round onto one grid, Draco in float and meshopt in double: a coordinate close to a
  // rounding boundary may land a step apart. None does on the bunny; 1 % of the corners of mtlod-gen's
  // painted shell and 7 % of the 871k dragon's (a marching-cubes scan: coordinates on its voxel grid
  // meet the boundaries often) have one. A decode a step off moves every corner.
  check(c.maxSteps <= 1.01 && c.offCorners <= 0.15 * c.corners,
        `${what}: corners on the same grid points in the same winding (coordinates at most ${c.maxSteps.toFixed(3)} steps apart; ` +
        `${c.offCorners} of ${c.corners} corners have one more than 0.1 step apart)`);
  if (keptDraco.normals || keptMeshopt.normals) {
    check(keptDraco.normals && keptMeshopt.normals && c.maxDegrees < 0.5,
          `${what}: the same normals, within the two 10-bit octahedral quantizations (largest angle ${c.maxDegrees.toFixed(3)}°)`);
  }
  if (keptDraco.colors || keptMeshopt.colors) {
    check(keptDraco.colors && keptMeshopt.colors && c.maxColour < 1e-6,
          `${what}: the same colours (largest difference ${c.maxColour})`);
  }
}

// The picture, panel and overlay hidden (they differ between the pages), two frames after the last mesh.
async function picture(viewer, name) {
  const show = (visibility) => viewer.page.evaluate((v) => {
    for (const id of ['panel', 'overlay']) document.getElementById(id).style.visibility = v;
  }, visibility);
  await show('hidden');
  await viewer.page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  const png = await viewer.page.screenshot({ path: path.join(args.out, `${name}-${viewer.codec}.png`) });
  await show('');
  return png;
}

try {
  server = await startServer(args.server, ['--mesh', args.mesh, ...(args.painted ? ['--mesh', args.painted] : [])],
                             args.out, 'viewer-codecs');
  if (!server.httpPort) throw new Error(`the server did not start: ${JSON.stringify(server.exit)}`);
  const origin = `http://127.0.0.1:${server.httpPort}`;
  browser = await chromium.launch({ executablePath: chromiumPath, args: chromiumArgs });
  const draco = await openViewer('draco', origin);
  const meshopt = await openViewer('meshopt', origin);

  // The first mesh: the whole cut, as a delta that starts the kept mesh.
  await Promise.all([settled(draco), settled(meshopt)]);
  const first = await shown(meshopt);
  const firstReply = meshopt.replies[0];
  check(meshopt.sent.some((r) => r.type === 'extract') && meshopt.sent.filter((r) => r.type === 'extract').every((r) => r.codec === 'meshopt'),
        'the meshopt page asks for meshopt payloads');
  check(draco.sent.filter((r) => r.type === 'extract').every((r) => r.codec === 'draco'), 'the Draco page asks for Draco payloads');
  check(firstReply && firstReply.json.codec === 'meshopt' && firstReply.json.bytes === firstReply.payload.length,
        `the reply names meshopt and has the announced size (${firstReply?.json.codec}, ${firstReply?.json.bytes} bytes)`);
  const meshPart = firstReply ? (firstReply.json.delta.payload_bytes ?? firstReply.json.delta.draco_bytes) : 0;
  check(firstReply && firstReply.payload.subarray(0, 4).toString('latin1') === 'MOPT' &&
        meshPart + 4 * firstReply.json.delta.added === firstReply.payload.length,
        `its payload is a MOPT container (${meshPart} bytes) and the ids of the ${firstReply?.json.delta.added} triangles`);
  check(first.triangles === first.reply.triangles && first.triangles > 0,
        `displayed triangles ${first.triangles} = the server's reply ${first.reply.triangles}`);
  check(firstReply && firstReply.json.delta.reset, `the first mesh starts the kept mesh (${JSON.stringify(firstReply?.json.delta)})`);
  check(first.normals && !first.flat, `the mesh has the server's normals and is smooth-shaded (${first.normals}, flat ${first.flat})`);
  check(first.errors.length === 0, `no error shown (${first.errors.join('; ')})`);
  check(await meshopt.page.isDisabled('#labels'), 'the label colouring, which meshopt payloads cannot carry, is off limits');
  await compareCodecs(draco, meshopt, 'first view');

  // The mouse moves the focus on both pages: a delta that applies.
  const target = [0.6, 0.45];
  for (const viewer of [draco, meshopt]) {
    const before = await viewer.page.evaluate(() => window.mtlod.meshes);
    await viewer.page.mouse.move(size.width * target[0], size.height * target[1]);
    await viewer.page.waitForFunction((want) => {
      const r = window.mtlod.lastReply;
      return r && r.focus && Math.abs(r.focus[0] - want[0]) < 0.01 && Math.abs(r.focus[1] - want[1]) < 0.01 && window.mtlod.idle();
    }, target, { timeout: 60_000 });
    await settled(viewer, before);
  }
  const gazed = await shown(meshopt);
  const gazedReply = replyTo(meshopt, gazed.reply.id);
  check(gazedReply && gazedReply.json.codec === 'meshopt' && gazedReply.json.delta && !gazedReply.json.delta.reset &&
        gazedReply.json.delta.added > 0 && gazedReply.json.delta.added < gazedReply.json.triangles,
        `the gaze's mesh came as a meshopt change to the kept one (${JSON.stringify(gazedReply?.json.delta)})`);
  check(gazed.triangles === gazed.reply.triangles && gazed.errors.length === 0,
        `the kept mesh holds the server's cut: ${gazed.triangles} = ${gazed.reply.triangles} triangles (errors: ${gazed.errors.join('; ')})`);
  check(gazed.normals && !gazed.flat, 'the kept mesh has the server\'s normals and is smooth-shaded');
  await compareCodecs(draco, meshopt, 'after the gaze');
  const [pictureDraco, pictureMeshopt] = [await picture(draco, 'codecs'), await picture(meshopt, 'codecs')];
  const pixels = await comparePictures(draco.page, pictureDraco, pictureMeshopt, kPixelThreshold, kBackground);
  check(pixels.covered > 0.05 * pixels.pixels, `the model covers ${(100 * pixels.covered / pixels.pixels).toFixed(1)} % of the picture`);
  check(pixels.over <= kMaxDifferingShare * pixels.covered && pixels.meanDifference <= kMaxMeanDifference,
        `the screenshots agree: ${pixels.over} pixels differ by more than ${kPixelThreshold} (at most ${(kMaxDifferingShare * 100).toFixed(1)} % of ` +
        `the model's ${pixels.covered}), mean difference ${pixels.meanDifference.toFixed(3)} (at most ${kMaxMeanDifference})`);

  // Damaged payloads: a delta's magic, then the whole mesh the page asks for after it loses its last
  // byte. Each shows an error; the page goes on and the next mesh shows.
  meshopt.damage.push(
    (frame, json, at) => (frame.write('MOPX', at, 'latin1'), frame),
    (frame, json, at) => {
      const shorter = frame.subarray(0, frame.length - 1);
      shorter.writeUInt32LE(shorter.readUInt32LE(4) - 1, 4);
      return shorter;
    });
  const beforeDamage = await shown(meshopt);
  await meshopt.page.mouse.move(size.width * 0.4, size.height * 0.55);
  await meshopt.page.waitForFunction((n) => window.mtlod.errors.length >= n + 2 && window.mtlod.idle(),
                                     beforeDamage.errors.length, { timeout: 60_000 });
  const damaged = await shown(meshopt);
  const errors = damaged.errors.slice(beforeDamage.errors.length);
  check(errors[0].includes('meshopt payload: the magic is not "MOPT"'), `a damaged delta is an error on the page (${errors[0]})`);
  check(errors[1].includes('meshopt payload: the triangles stream') && errors[1].includes('run past the end'),
        `a damaged whole mesh too (${errors[1]})`);
  const damagedReplies = meshopt.replies.slice(-2).map((r) => r.json);
  check(damagedReplies[0].delta && !damagedReplies[1].delta, 'the page asked for a whole mesh after the damaged delta');
  check(damaged.meshes === beforeDamage.meshes && damaged.triangles === beforeDamage.triangles,
        'the mesh shown stays as it was while payloads do not decode');
  await meshopt.page.mouse.move(size.width * 0.5, size.height * 0.5);
  await settled(meshopt, damaged.meshes);
  const recovered = await shown(meshopt);
  check(recovered.triangles === recovered.reply.triangles && recovered.errors.length === damaged.errors.length && recovered.status === 'ok',
        `the page goes on: the next mesh shows (${recovered.triangles} = ${recovered.reply.triangles} triangles, status ${recovered.status})`);

  if (args.painted) {
    // A coloured model: colours in meshopt deltas, the same as Draco's.
    for (const viewer of [draco, meshopt]) {
      await viewer.page.mouse.move(size.width * target[0], size.height * target[1]);
      const before = await viewer.page.evaluate(() => window.mtlod.meshes);
      await viewer.page.selectOption('#model', 'painted');
      await viewer.page.waitForFunction((n) => window.mtlod.meshes > n && window.mtlod.lastReply.model === 'painted' && window.mtlod.idle(),
                                        before, { timeout: 60_000 });
    }
    const painted = await shown(meshopt);
    const paintedReplies = meshopt.replies.filter((r) => r.json.model === 'painted');
    check(painted.colours && painted.triangles === painted.reply.triangles && paintedReplies[0].json.delta?.reset &&
          paintedReplies.every((r) => r.json.codec === 'meshopt' && r.json.delta),
          `the painted model's colours come in meshopt deltas and are shown (${painted.colours}; ${painted.triangles} = ${painted.reply.triangles} triangles)`);
    check(meshopt.sent.filter((r) => r.type === 'extract' && r.model === 'painted').every((r) => r.attributes.colors === true),
          'the page asks for the painted model\'s colours');
    await compareCodecs(draco, meshopt, 'painted model');
    await picture(meshopt, 'codecs-painted');
  }

  // The panel's choice: the Draco page switches to meshopt, and gets one whole mesh in it.
  const beforeSwitch = await draco.page.evaluate(() => window.mtlod.meshes);
  await draco.page.selectOption('#codec', 'meshopt');
  await draco.page.waitForFunction((n) => window.mtlod.meshes > n && window.mtlod.lastReply.codec === 'meshopt' && window.mtlod.idle(),
                                   beforeSwitch, { timeout: 60_000 });
  const switched = await shown(draco);
  check(draco.sent.at(-1).codec === 'meshopt' && switched.reply.delta === undefined && switched.triangles === switched.reply.triangles,
        `the codec chosen in the panel goes out with the next extract, which asks for a whole mesh (${switched.triangles} triangles)`);
} catch (error) {
  console.log(`FAIL ${error.stack ?? error}`);
  results.failures += 1;
} finally {
  await finish({ browser, server, deadline });
}
