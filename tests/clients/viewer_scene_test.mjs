// Browser test of the viewer's scenes (protocol/PROTOCOL.md, "Scenes"): starts the real mtlod-server
// serving two models (the bunny and a painted shell with vertex colours), opens the page's built-in room
// (?scene=room) in headless Debian Chromium, and checks it against what crossed the WebSocket (read here
// from the frames, not from the page) and against the pixels drawn:
// - the page sends one scene extract of 12 to 20 instances mixing the served models, each matrix affine,
//   a rotation about the vertical with a uniform scale that brings the model's box to a size common to
//   all, standing on one floor; the one mesh reply lists an entry per instance and its payload is their
//   parts together;
// - the page draws one three.js mesh per instance and no other, each with the reply's triangles for it,
//   the model's colours when it has them, and the matrix the page sent as its matrixWorld;
// - the canvas has model pixels inside every instance's projected box (by the request's own camera
//   matrices) and next to none outside all of them;
// - a pointer move sends a gaze answered by a scene reply of per-instance deltas; after a few moves every
//   instance's kept mesh holds exactly the triangles the server names for it;
// - an orbit re-extracts the scene; whole meshes (delta off) and meshopt payloads show the same way;
//   the scene survives a round trip through a single model with its kept meshes right.
// Saves a screenshot of the room into --out.
//
// node viewer_scene_test.mjs --server BIN --mesh bunny.ply --painted painted.ply --out DIR
import fs from 'node:fs';
import path from 'node:path';
import { check, chromium, chromiumArgs, chromiumOrSkip, finish, parseArgs, results, startServer } from './browser_support.mjs';

const args = parseArgs(process.argv.slice(2), ['server', 'mesh', 'painted', 'out']);
const chromiumPath = chromiumOrSkip();
for (const mesh of [args.mesh, args.painted]) {
  if (!fs.existsSync(mesh)) {
    console.log(`skipped: ${mesh} is missing (scripts/prepare-models.sh and the viewer_painted fixture write them)`);
    process.exit(77);
  }
}

const size = { width: 800, height: 600 };
const kBackground = [0x20, 0x24, 0x28];  // viewer.js's scene.background
// A pixel is the model's when a channel is further than this from the background: antialiased edges
// blend into it, and no lit surface of the light models comes this close to it.
const kBackgroundDistance = 8;
// Projected boxes are widened by this many pixels: antialiasing reaches a pixel past the silhouette.
const kEdgePx = 2;
// Geometric checks on the matrices are exact but for double rounding of a few products (1e-12 relative).
const kRelative = 1e-9;

const deadline = setTimeout(() => {
  console.log('FAIL the test did not finish within 170 s');
  process.exit(1);
}, 170_000);

// Column-major 4×4 matrix (as the protocol sends them) times a point [x, y, z, 1].
const transform = (m, p) => [0, 1, 2, 3].map((r) => m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r]);
const corners = (lo, hi) => [0, 1, 2, 3, 4, 5, 6, 7].map((k) => [k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1], k & 4 ? hi[2] : lo[2]]);
const close = (a, b, scale) => Math.abs(a - b) <= kRelative * scale;

let server = null, browser = null;
try {
  server = await startServer(args.server, ['--mesh', args.mesh, '--mesh', args.painted], args.out, 'scene');
  if (!server.httpPort) throw new Error(`the server did not start: ${JSON.stringify(server.exit)}`);
  browser = await chromium.launch({ executablePath: chromiumPath, args: chromiumArgs });
  const page = await browser.newPage({ viewport: size });
  page.on('console', (m) => { if (m.type() === 'error') console.log(`page console: ${m.text()}`); });
  page.on('pageerror', (e) => console.log(`page error: ${e.message}`));

  // What crossed the WebSocket: requests by id, mesh replies with their payload's size, the models served
  // and their model_info replies.
  const sent = new Map(), replies = new Map(), infos = new Map();
  let served = [];
  page.on('websocket', (ws) => {
    ws.on('framesent', ({ payload }) => {
      const json = JSON.parse(typeof payload === 'string' ? payload : payload.toString('utf8'));
      sent.set(json.id, json);
    });
    ws.on('framereceived', ({ payload }) => {
      let json, payloadBytes = 0;
      if (typeof payload === 'string') {
        json = JSON.parse(payload);
      } else {
        const jsonBytes = payload.readUInt32LE(0);
        payloadBytes = payload.readUInt32LE(4);
        json = JSON.parse(payload.subarray(8, 8 + jsonBytes).toString('utf8'));
      }
      if (json.type === 'mesh') replies.set(json.id, { json, payloadBytes });
      if (json.type === 'model_info') infos.set(sent.get(json.id)?.model, json);
      if (json.type === 'models') served = json.models.map((m) => m.name);
    });
  });
  // The extract a reply answers: its own request, or for a gaze the latest extract before it.
  const extractOf = (id) => [...sent.values()].filter((r) => r.type === 'extract' && r.id <= id).at(-1);
  const frames = () => page.evaluate(() => new Promise((resolve) => requestAnimationFrame(() => requestAnimationFrame(resolve))));
  // Waits until the page has shown a reply newer than `after` and has nothing more to send or receive.
  const settle = async (after, what) => {
    await page.waitForFunction((id) => window.mtlod && window.mtlod.lastReply && window.mtlod.lastReply.id > id &&
                                       window.mtlod.idle(), after, { timeout: 60_000 });
    await frames();  // a frame drawn with what was shown, so matrixWorld and the canvas are current
    const shown = await page.evaluate(() => ({
      id: window.mtlod.lastReply.id, instances: window.mtlod.instances(), drawn: window.mtlod.drawnMeshes(),
      errors: [...window.mtlod.errors], displayed: window.mtlod.displayedTriangles,
    }));
    shown.reply = replies.get(shown.id);
    shown.request = extractOf(shown.id);
    if (!shown.reply) throw new Error(`${what}: the reply ${shown.id} shown did not cross the WebSocket`);
    return shown;
  };
  // The page shows the scene reply it holds: a mesh per instance with that instance's triangles (and the
  // kept mesh's size when it came as deltas), placed by the matrix sent.
  const checkShown = (shown, what) => {
    const { json } = shown.reply;
    const instances = json.instances ?? [];
    const sentInstances = shown.request?.scene?.instances ?? [];
    check(instances.length === sentInstances.length && instances.length > 0,
          `${what}: a scene reply of ${instances.length} instances for the ${sentInstances.length} sent`);
    check(shown.drawn === instances.length && shown.instances.length === instances.length,
          `${what}: the page draws ${shown.drawn} three.js meshes (${shown.instances.length} instances), one per instance`);
    const wrong = instances.map((instance, i) => [i, instance.triangles, shown.instances[i]?.triangles])
      .filter(([, want, got]) => want !== got);
    check(wrong.length === 0, `${what}: every mesh has its instance's triangles (wrong: ${JSON.stringify(wrong.slice(0, 4))})`);
    const misplaced = sentInstances.filter((instance, i) =>
      !shown.instances[i] || shown.instances[i].matrixWorld.some((value, k) => value !== instance.matrix[k]));
    check(misplaced.length === 0, `${what}: every mesh's matrixWorld is the matrix sent for its instance (${misplaced.length} differ)`);
    if (instances.every((instance) => instance.delta)) {
      const off = instances.map((instance, i) => [i, instance.triangles, shown.instances[i]?.kept])
        .filter(([, want, got]) => want !== got);
      check(off.length === 0, `${what}: every instance's kept mesh holds its triangles (off: ${JSON.stringify(off.slice(0, 4))})`);
    }
    check(json.triangles === instances.reduce((sum, instance) => sum + instance.triangles, 0) &&
          json.bytes === shown.reply.payloadBytes &&
          shown.reply.payloadBytes === instances.reduce((sum, instance) => sum + instance.bytes, 0),
          `${what}: the reply's ${json.triangles} triangles and ${json.bytes} bytes are its instances' (payload ${shown.reply.payloadBytes})`);
    check(shown.displayed === json.triangles, `${what}: the page shows ${shown.displayed} triangles in all, the reply's ${json.triangles}`);
    check(shown.errors.length === 0, `${what}: no error shown (${shown.errors.join('; ')})`);
  };

  await page.goto(`http://127.0.0.1:${server.httpPort}/?scene=room`);
  const first = await settle(0, 'room');
  const request = first.request;
  const sceneInstances = request?.scene?.instances ?? [];

  // The scene as sent: one extract naming a room of instances, no model.
  check(request && request.model === undefined && sceneInstances.length >= 12 && sceneInstances.length <= 20,
        `one extract names a scene of ${sceneInstances.length} instances (12 to 20) instead of a model`);
  const models = new Set(sceneInstances.map((instance) => instance.model));
  check(served.length === 2 && models.size === 2 && served.every((m) => models.has(m)),
        `the room mixes the served models (${[...models].join(', ')} of ${served.join(', ')})`);
  check(sceneInstances.length > models.size, 'models repeat: instances of one model share it');
  const boxes = sceneInstances.map((instance) => {
    const info = infos.get(instance.model), m = instance.matrix;
    const affine = m.length === 16 && m.every(Number.isFinite) && m[3] === 0 && m[7] === 0 && m[11] === 0 && m[15] === 1;
    // The linear part's columns: a rotation with a uniform scale has them orthogonal and of one length.
    const columns = [0, 1, 2].map((c) => m.slice(4 * c, 4 * c + 3));
    const lengths = columns.map((c) => Math.hypot(...c));
    const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    const similar = close(lengths[0], lengths[1], lengths[0]) && close(lengths[0], lengths[2], lengths[0]) &&
      [[0, 1], [0, 2], [1, 2]].every(([a, b]) => Math.abs(dot(columns[a], columns[b])) <= kRelative * lengths[0] ** 2);
    const upright = Math.abs(m[1]) <= kRelative * lengths[0] && Math.abs(m[9]) <= kRelative * lengths[0];
    const extent = Math.max(...info.bounds_max.map((hi, k) => hi - info.bounds_min[k]));
    const world = corners(info.bounds_min, info.bounds_max).map((p) => transform(m, p));
    return { affine, similar, upright, size: lengths[0] * extent, floor: Math.min(...world.map((p) => p[1])), world };
  });
  check(boxes.every((b) => b.affine), 'every matrix is 16 finite numbers, affine (last row 0, 0, 0, 1)');
  check(boxes.every((b) => b.similar && b.upright), 'every matrix turns about the vertical and scales uniformly');
  const common = boxes[0]?.size ?? 0;
  check(common > 0 && boxes.every((b) => close(b.size, common, common)),
        `every instance's box has one largest side in the world (${boxes.map((b) => b.size.toPrecision(6)).join(', ')})`);
  check(boxes.every((b) => close(b.floor, boxes[0].floor, common)),
        `every instance stands on one floor (lowest world y ${boxes.map((b) => b.floor.toPrecision(3)).join(', ')})`);

  // The reply: one mesh reply with an entry per instance, in order, each part a delta that starts afresh.
  const { json } = first.reply;
  check(json.instances?.length === sceneInstances.length &&
        json.instances.every((instance, i) => instance.model === sceneInstances[i].model),
        'the reply lists every instance in the request\'s order, each with its model');
  checkShown(first, 'room');
  const firstFrame = [...replies.values()].find((r) => r.json.instances)?.json;
  check(firstFrame && firstFrame.instances.every((instance) => instance.delta && instance.delta.reset),
        'delta updates are on: the first scene reply starts every instance\'s kept mesh');
  const colours = json.instances.map((instance, i) => [first.instances[i]?.colors, infos.get(instance.model).colors === true]);
  check(colours.every(([shown, has]) => shown === has) && colours.some(([, has]) => has),
        'instances of the painted model show its colours, the others none');
  const overlay = await page.evaluate(() => Object.fromEntries(['instances', 'triangles', 'bytes', 'server-ms']
    .map((id) => [id, document.getElementById(id).textContent])));
  check(overlay.instances === String(json.instances.length) && overlay.triangles === String(json.triangles) &&
        overlay.bytes === String(json.bytes) && overlay['server-ms'] === (json.timings_us.total / 1000).toFixed(1),
        `the status line shows the scene's totals (${JSON.stringify(overlay)})`);
  console.log(`     room: ${json.instances.length} instances, ${json.triangles} triangles, ${json.bytes} bytes, ` +
              `server ${json.timings_us.total} us (${JSON.stringify(json.timings_us)})`);

  // Pixels: each instance's box projected by the request's camera holds model pixels, and next to none lie
  // outside every box. The canvas is read as drawn (the viewer keeps its drawing buffer), without the panel.
  const { view, projection, viewport } = request.camera;
  const rects = boxes.map((b) => {
    const screen = b.world.map((p) => {
      const clip = transform(projection, transform(view, [p[0], p[1], p[2]]));
      return [(clip[0] / clip[3] + 1) / 2 * viewport[0], (1 - clip[1] / clip[3]) / 2 * viewport[1], clip[3]];
    });
    return { x0: Math.min(...screen.map((s) => s[0])), x1: Math.max(...screen.map((s) => s[0])),
             y0: Math.min(...screen.map((s) => s[1])), y1: Math.max(...screen.map((s) => s[1])),
             front: screen.every((s) => s[2] > 0) };
  });
  check(rects.every((r) => r.front && r.x1 > 0 && r.x0 < viewport[0] && r.y1 > 0 && r.y0 < viewport[1]),
        'every instance lies in front of the camera and on the screen');
  const overlapping = rects.filter((r, i) => rects.some((s, j) => j !== i && r.x0 < s.x1 && s.x0 < r.x1 && r.y0 < s.y1 && s.y0 < r.y1));
  check(overlapping.length > 0, `instances overlap on the screen, some partly hiding others (${overlapping.length} of ${rects.length})`);
  const pixels = await page.evaluate(({ rects, background, distance, edge, viewport }) => {
    const canvas = document.querySelector('#view canvas');
    const copy = new OffscreenCanvas(canvas.width, canvas.height);
    const context = copy.getContext('2d');
    context.drawImage(canvas, 0, 0);
    const data = context.getImageData(0, 0, canvas.width, canvas.height).data;
    const sx = canvas.width / viewport[0], sy = canvas.height / viewport[1];
    const inside = rects.map(() => 0), area = rects.map(() => 0);
    let covered = 0, outside = 0;
    for (let y = 0; y < canvas.height; ++y) {
      for (let x = 0; x < canvas.width; ++x) {
        const i = 4 * (y * canvas.width + x);
        const model = [0, 1, 2].some((k) => Math.abs(data[i + k] - background[k]) > distance);
        let anywhere = false;
        rects.forEach((r, k) => {
          const px = (x + 0.5) / sx, py = (y + 0.5) / sy;
          if (px >= r.x0 - edge && px <= r.x1 + edge && py >= r.y0 - edge && py <= r.y1 + edge) {
            anywhere = true;
            area[k] += 1;
            if (model) inside[k] += 1;
          }
        });
        if (model) covered += 1;
        if (model && !anywhere) outside += 1;
      }
    }
    return { inside, area, covered, outside };
  }, { rects, background: kBackground, distance: kBackgroundDistance, edge: kEdgePx, viewport });
  const thin = pixels.inside.map((n, i) => [i, n, pixels.area[i]]).filter(([, n, a]) => n < 0.05 * a);
  check(thin.length === 0, `model pixels cover at least 5 % of every instance's projected box (short: ${JSON.stringify(thin)})`);
  check(pixels.covered > 0 && pixels.outside <= 0.001 * pixels.covered,
        `model pixels lie where instances project: ${pixels.outside} of ${pixels.covered} outside every box`);
  const screenshot = path.join(args.out, 'viewer-room.png');
  await page.screenshot({ path: screenshot });
  check(fs.statSync(screenshot).size > 1000, `screenshot saved to ${screenshot}`);

  // A gaze: the pointer moves, a gaze goes out and a scene reply of per-instance deltas comes back.
  const target = [0.6, 0.45];  // clear of the panel at the top left
  await page.mouse.move(size.width * target[0], size.height * target[1]);
  const gazed = await settle(first.id, 'gaze');
  const gaze = sent.get(gazed.id);
  check(gaze?.type === 'gaze' && Math.abs(gaze.x - target[0]) < 0.01 && Math.abs(gaze.y - target[1]) < 0.01,
        `the pointer move sent a gaze at ${target} (${JSON.stringify(gaze)})`);
  check(gazed.reply.json.focus && Math.abs(gazed.reply.json.focus[0] - target[0]) < 0.01,
        `a scene reply reflects the new focus ${JSON.stringify(gazed.reply.json.focus)}`);
  check(gazed.reply.json.instances?.every((instance) => instance.delta && !instance.delta.reset),
        'it came as changes to every instance\'s kept mesh');
  checkShown(gazed, 'gaze');

  // A few more moves: every instance's kept mesh still holds exactly the server's cut.
  let last = gazed.id;
  for (const [x, y] of [[0.45, 0.55], [0.75, 0.35], [0.55, 0.7], [0.65, 0.5]]) {
    await page.mouse.move(size.width * x, size.height * y, { steps: 3 });
    await page.waitForTimeout(30);
  }
  const moved = await settle(last, 'moves');
  const changed = [...replies.values()].filter((r) => r.json.id > last && r.json.instances)
    .reduce((sum, r) => sum + r.json.instances.reduce((s, i) => s + (i.delta?.added ?? 0) + (i.delta?.removed ?? 0), 0), 0);
  check(changed > 0, `the moves' replies changed the kept meshes (${changed} triangles added or removed)`);
  checkShown(moved, 'after moves');
  last = moved.id;

  // An orbit (a drag) re-extracts the scene from the new view.
  await page.mouse.move(500, 300);
  await page.mouse.down();
  await page.mouse.move(560, 290, { steps: 5 });
  await page.mouse.up();
  const orbited = await settle(last, 'orbit');
  check(orbited.request.id > last && orbited.request.scene &&
        orbited.request.camera.view.some((v, k) => v !== request.camera.view[k]),
        `the orbit sent a scene extract with a new view (request ${orbited.request.id})`);
  checkShown(orbited, 'orbit');
  last = orbited.id;

  // Whole meshes (delta off), then meshopt payloads, then deltas again in meshopt.
  await page.uncheck('#delta');
  const whole = await settle(last, 'whole');
  check(whole.reply.json.instances?.every((instance) => instance.delta === undefined), 'with delta off, whole meshes per instance');
  checkShown(whole, 'whole');
  await page.selectOption('#codec', 'meshopt');
  const meshopt = await settle(whole.id, 'meshopt');
  check(meshopt.request.codec === 'meshopt' && meshopt.reply.json.codec === 'meshopt', 'the panel\'s codec: meshopt payloads');
  checkShown(meshopt, 'meshopt');
  await page.check('#delta');
  const meshoptDelta = await settle(meshopt.id, 'meshopt delta');
  check(meshoptDelta.reply.json.instances?.every((instance) => instance.delta), 'meshopt deltas per instance');
  checkShown(meshoptDelta, 'meshopt delta');
  last = meshoptDelta.id;

  // A single model, then the room again: one mesh, then the instances, their kept meshes still right.
  await page.selectOption('#scene', '');
  const single = await settle(last, 'single model');
  check(single.reply.json.instances === undefined && single.request.model && single.drawn === 1 && single.instances.length === 0,
        `no scene: one model, one mesh drawn (${single.drawn})`);
  await page.selectOption('#scene', 'room');
  const again = await settle(single.id, 'room again');
  checkShown(again, 'room again');
  await page.mouse.move(size.width * 0.5, size.height * 0.4);
  checkShown(await settle(again.id, 'room again, gaze'), 'room again, gaze');
} catch (error) {
  console.log(`FAIL ${error.stack ?? error}`);
  results.failures += 1;
} finally {
  await finish({ browser, server, deadline });
}
