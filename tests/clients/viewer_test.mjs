// Browser test of the viewer: starts the real mtlod-server with HTTP on an OS-chosen port,
// drives clients/web/ in headless Debian Chromium through playwright-core, and checks what the page
// shows against the server's replies as they crossed the WebSocket (read here from the frames, not
// from the page): a mesh arrives, the displayed triangle count (counted from the decoded Draco
// index) equals the reply's `triangles`, and moving the mouse sends a gaze whose mesh reflects the
// new focus. Saves a screenshot into --out.
//
// With --painted PLY the server also serves that coloured mesh: the page asks for its colours and
// shows them, through delta replies too.
//
// With --tls the server runs with a certificate made here by openssl and an access token
// (--tls-cert, --tls-key, --auth-tokens): the page loads over https with ?token=, its WebSocket is
// wss and carries the token, and it shows a mesh; a page without the token gets no connection.
//
// node viewer_test.mjs [--tls] --server BIN --mesh bunny.ply [--painted painted.ply] --out DIR
import { spawn, spawnSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { check, chromium, chromiumArgs, chromiumOrSkip, comparePictures, parseArgs, results, root, sleep, waitForHttpPort }
  from './browser_support.mjs';

const tls = process.argv.includes('--tls');
const args = parseArgs(process.argv.slice(2), ['server', 'mesh', 'out'], ['--tls']);
const chromiumPath = chromiumOrSkip();
if (!fs.existsSync(args.mesh)) {
  console.log(`skipped: ${args.mesh} is missing (scripts/prepare-models.sh writes it)`);
  process.exit(77);
}

// With --tls: a certificate for 127.0.0.1 and a tokens file, both made for this run.
const token = 'viewer-test-token-0123456789abcdef';
const security = [];
if (tls) {
  const cert = path.join(args.out, 'viewer-cert.pem'), key = path.join(args.out, 'viewer-key.pem');
  const made = spawnSync('openssl', ['req', '-x509', '-newkey', 'rsa:2048', '-nodes', '-days', '2', '-subj', '/CN=127.0.0.1',
                                     '-addext', 'subjectAltName=IP:127.0.0.1', '-keyout', key, '-out', cert],
                         { encoding: 'utf8' });
  if (made.status !== 0) throw new Error(`openssl failed: ${made.error ?? made.stderr}`);
  const tokens = path.join(args.out, 'viewer-tokens.txt');
  fs.writeFileSync(tokens, `${token}\n`);
  security.push('--tls-cert', cert, '--tls-key', key, '--auth-tokens', tokens);
}

// The server, with the port file telling both ports (protocol, then HTTP).
const portFile = path.join(args.out, 'viewer-ports');
fs.rmSync(portFile, { force: true });
const serverLog = fs.openSync(path.join(args.out, 'viewer-server.log'), 'w');
const painted = args.painted ? ['--mesh', args.painted] : [];
const server = spawn(args.server, ['--mesh', args.mesh, ...painted, '--cache-dir', args.out, '--port', '0', '--http-port', '0',
                                   '--port-file', portFile, '--web-root', root, '--workers', '2', '--log-level', 'info', ...security],
                     { stdio: ['ignore', serverLog, serverLog] });
let serverExit = null;
server.on('exit', (code, signal) => { serverExit = { code, signal }; });

let browser = null;
const deadline = setTimeout(() => {
  console.log('FAIL the test did not finish within 90 s');
  server.kill('SIGKILL');
  process.exit(1);
}, 90_000);

try {
  const httpPort = await waitForHttpPort(portFile, () => !serverExit, 600);
  if (!httpPort) throw new Error(`the server did not start: ${JSON.stringify(serverExit)}`);

  browser = await chromium.launch({
    executablePath: chromiumPath,
    args: [...chromiumArgs,
           // The test's certificate is self-signed: no browser trusts it.
           ...(tls ? ['--ignore-certificate-errors'] : [])],
  });
  const page = await browser.newPage({ viewport: { width: 800, height: 600 }, ignoreHTTPSErrors: tls });
  page.on('console', (m) => { if (m.type() === 'error') console.log(`page console: ${m.text()}`); });
  page.on('pageerror', (e) => console.log(`page error: ${e.message}`));

  // The server's replies and the page's requests, read off the WebSocket.
  const meshReplies = [];
  const gazesSent = [];
  const sockets = [];
  const extractsSent = [];
  page.on('websocket', (ws) => {
    sockets.push(ws.url());
    ws.on('framereceived', ({ payload }) => {
      if (typeof payload === 'string') {
        // JSON-only replies: hello, models, errors, and a delta that changed nothing.
        const json = JSON.parse(payload);
        if (json.type === 'mesh') meshReplies.push({ json, dracoBytes: 0 });
        return;
      }
      const jsonBytes = payload.readUInt32LE(0), payloadBytes = payload.readUInt32LE(4);
      const json = JSON.parse(payload.subarray(8, 8 + jsonBytes).toString('utf8'));
      if (json.type === 'mesh') meshReplies.push({ json, dracoBytes: payloadBytes });
    });
    ws.on('framesent', ({ payload }) => {
      const json = JSON.parse(typeof payload === 'string' ? payload : payload.toString('utf8'));
      if (json.type === 'gaze') gazesSent.push(json);
      if (json.type === 'extract') extractsSent.push(json);
    });
  });

  const origin = `${tls ? 'https' : 'http'}://127.0.0.1:${httpPort}`;
  await page.goto(tls ? `${origin}/?token=${token}` : `${origin}/`);
  await page.waitForFunction(() => window.mtlod && window.mtlod.meshes >= 1, null, { timeout: 30_000 });
  const first = await page.evaluate(() => ({ id: window.mtlod.lastReply.id, shown: document.getElementById('triangles').textContent,
                                           errors: window.mtlod.errors }));
  const firstReply = meshReplies.find((r) => r.json.id === first.id);
  check(firstReply !== undefined, `the mesh shown (request ${first.id}) crossed the WebSocket`);
  check(firstReply && firstReply.json.bytes === firstReply.dracoBytes, 'its Draco payload has the announced size');
  check(firstReply && Number(first.shown) === firstReply.json.triangles && firstReply.json.triangles > 0,
        `displayed triangles ${first.shown} = the server's reply ${firstReply?.json.triangles}`);
  check(first.errors.length === 0, `no error shown (${first.errors.join('; ')})`);
  check(meshReplies.length > 0 && meshReplies[0].json.delta && meshReplies[0].json.delta.reset,
        `delta updates are on by default: the first mesh starts the kept mesh (${JSON.stringify(meshReplies[0]?.json.delta)})`);

  // Over TLS, what TLS and the token change; in the clear, gazes, deltas and labels.
  if (tls) {
    check(sockets.length === 1 && sockets[0] === `wss://127.0.0.1:${httpPort}/ws?token=${token}`,
          `the WebSocket is wss and carries the page's token (${sockets.join(', ')})`);
    await page.screenshot({ path: path.join(args.out, 'viewer-https.png') });
    // Without the token the upgrade is refused (401): the page says so and shows no mesh.
    const refused = await browser.newPage({ viewport: { width: 800, height: 600 }, ignoreHTTPSErrors: true });
    await refused.goto(`${origin}/`);
    await refused.waitForFunction(() => window.mtlod && window.mtlod.errors.length > 0, null, { timeout: 30_000 });
    const status = await refused.evaluate(() => ({ meshes: window.mtlod.meshes, text: document.getElementById('status').textContent }));
    check(status.meshes === 0 && status.text.includes('token'), `without ?token= no connection, and the page says why (${status.text})`);
    await refused.close();
  } else {
    // The mouse is the focus: a gaze goes out and a mesh reflecting it comes back.
    const target = [0.6, 0.45];  // clear of the control panel at the top left
    const before = meshReplies.length;
    await page.mouse.move(800 * target[0], 600 * target[1]);
    await page.waitForFunction((want) => {
      const r = window.mtlod.lastReply;
      return r && r.focus && Math.abs(r.focus[0] - want[0]) < 0.01 && Math.abs(r.focus[1] - want[1]) < 0.01;
    }, target, { timeout: 30_000 });
    const second = await page.evaluate(() => ({ id: window.mtlod.lastReply.id, shown: document.getElementById('triangles').textContent,
                                              focus: document.getElementById('focus-point').textContent }));
    const secondReply = meshReplies.find((r) => r.json.id === second.id);
    check(meshReplies.length > before, `a new mesh arrived after the mouse moved (${meshReplies.length - before})`);
    check(gazesSent.some((g) => Math.abs(g.x - target[0]) < 0.01 && Math.abs(g.y - target[1]) < 0.01),
          `a gaze at ${target} was sent (${JSON.stringify(gazesSent.at(-1))})`);
    check(secondReply && secondReply.json.focus && Math.abs(secondReply.json.focus[0] - target[0]) < 0.01,
          `the server's mesh reflects the new focus ${JSON.stringify(secondReply?.json.focus)}`);
    check(secondReply && Number(second.shown) === secondReply.json.triangles,
          `displayed triangles ${second.shown} = the reply's ${secondReply?.json.triangles}`);
    check(second.focus === `${target[0].toFixed(3)}, ${target[1].toFixed(3)}`, `the overlay shows the focus (${second.focus})`);
    check(secondReply && secondReply.json.delta && !secondReply.json.delta.reset &&
          secondReply.json.delta.added < secondReply.json.triangles,
          `the gaze's mesh came as a change to the kept one (${JSON.stringify(secondReply?.json.delta)}), and the page shows the server's count`);

    // The mesh kept from deltas, as shown: smooth-shaded with the server's normals.
    const shading = await page.evaluate(() => ({ normals: window.mtlod.lastReplyHadNormals, flat: window.mtlod.flatShading }));
    check(shading.normals === true && shading.flat === false,
          `the kept mesh carries the server's normals and is smooth-shaded (${JSON.stringify(shading)})`);
    check(extractsSent.every((e) => e.attributes.normals === true), 'the page asks for normals');
    const smooth = await page.screenshot({ path: path.join(args.out, 'viewer-delta.png') });
    await page.check('#flat');
    await page.waitForFunction(() => window.mtlod.flatShading === true, null, { timeout: 10_000 });
    await page.waitForTimeout(200);  // a frame drawn with the new material
    const flat = await page.screenshot({ path: path.join(args.out, 'viewer-flat.png') });
    // Smooth shading with the server's normals shows: the facets' own normals light many pixels otherwise.
    const facets = await comparePictures(page, smooth, flat, 8, [0x20, 0x24, 0x28]);
    check(facets.over > 0.01 * facets.covered,
          `flat shading, a toggle, changes the picture (${facets.over} of ${facets.covered} pixels by more than 8 levels)`);
    await page.uncheck('#flat');

    // Colouring by distance label: the page asks for labels and decodes the generic attribute.
    await page.check('#labels');
    await page.waitForFunction((id) => window.mtlod.lastReply.id > id, second.id, { timeout: 30_000 });
    const labelled = await page.evaluate(() => window.mtlod.lastReplyHadLabels);
    check(labelled === true, 'with labels on, the decoded mesh carries the label attribute');
    const whole = await page.evaluate(() => window.mtlod.lastReply.delta === undefined);
    check(whole, 'with labels on, whole meshes replace the kept one (labels would go stale in deltas)');

    const screenshot = path.join(args.out, 'viewer.png');
    await page.screenshot({ path: screenshot });
    check(fs.statSync(screenshot).size > 1000, `screenshot saved to ${screenshot}`);

    if (args.painted) {
      // A coloured model: its colours come in the Draco payload (COLOR) and are what the page shows.
      await page.uncheck('#labels');
      const before = await page.evaluate(() => window.mtlod.lastReply.id);
      await page.selectOption('#model', 'painted');
      await page.waitForFunction((id) => window.mtlod.lastReply.id > id && window.mtlod.lastReply.model === 'painted',
                                 before, { timeout: 30_000 });
      const shown = await page.evaluate(() => ({ colours: window.mtlod.lastReplyHadColors, delta: window.mtlod.lastReply.delta,
                                                 errors: window.mtlod.errors.length }));
      const asked = extractsSent.filter((e) => e.model === 'painted');
      check(asked.length > 0 && asked.every((e) => e.attributes.colors === true), 'the page asks for the painted model\'s colours');
      check(shown.colours === true, 'the mesh shown carries the model\'s vertex colours');
      check(shown.delta !== undefined, `they came in a delta reply (${JSON.stringify(shown.delta)})`);
      await page.screenshot({ path: path.join(args.out, 'viewer-colours.png') });
    }
  }
} catch (error) {
  console.log(`FAIL ${error.stack ?? error}`);
  results.failures += 1;
} finally {
  if (browser) await browser.close();
  if (!serverExit) {
    server.kill('SIGTERM');
    for (let i = 0; i < 200 && !serverExit; ++i) await sleep(50);
  }
  check(serverExit && serverExit.code === 0, `the server drained and exited cleanly (${JSON.stringify(serverExit)})`);
  if (!serverExit) server.kill('SIGKILL');
  clearTimeout(deadline);
}
process.exit(results.failures ? 1 : 0);
