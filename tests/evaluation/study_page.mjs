// What the studies on the viewer's own pixels share (viewer_study.mjs, scene_study.mjs): the server
// they drive, the panel set as a user sets it, the picture as shown, and its score.
import { execFileSync, spawn } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { root, waitForHttpPort } from '../clients/browser_support.mjs';

export const kBackground = '202428';  // the page's scene.background

// mtlod-server on OS-chosen ports serving `meshes` (MTs built into cacheDir on first use) and this
// tree's viewer (or webRoot's); its log in work/server.log. Resolves to { server, httpPort }.
export async function startStudyServer({ binary, meshes, work, cacheDir, webRoot, extra = [] }) {
  const portFile = path.join(work, 'ports');
  fs.rmSync(portFile, { force: true });
  const log = fs.openSync(path.join(work, 'server.log'), 'w');
  const server = spawn(binary, [...meshes.flatMap((m) => ['--mesh', m]), '--cache-dir', cacheDir, '--port', '0',
                                '--http-port', '0', '--port-file', portFile, '--web-root', webRoot ?? root,
                                '--log-level', 'warn', ...extra], { stdio: ['ignore', log, log] });
  let exited = null;
  server.on('exit', (code, signal) => { exited = { code, signal }; });
  const httpPort = await waitForHttpPort(portFile, () => !exited, 6000);
  if (httpPort) return { server, httpPort };
  server.kill('SIGKILL');
  throw new Error(`the server did not start: ${JSON.stringify(exited)} (see ${work}/server.log)`);
}

// Sets the panel's controls as a user would (a change event each, which asks for a new view), then
// waits until the page has shown the reply to the last request.
export async function extract(page, controls) {
  const before = await page.evaluate(() => window.mtlod.meshes);
  await page.evaluate((c) => {
    for (const [id, value] of Object.entries(c)) {
      const input = document.getElementById(id);
      if (input.type === 'checkbox') input.checked = value;
      else input.value = String(value);
      input.dispatchEvent(new Event('change'));
    }
  }, controls);
  await page.waitForFunction((n) => window.mtlod.idle() && window.mtlod.meshes > n, before, { timeout: 300_000 });
  const reply = await page.evaluate(() => window.mtlod.lastReply);
  if (reply.type !== 'mesh') throw new Error(`no mesh: ${JSON.stringify(reply)}`);
  return reply;
}

// The picture as shown: two frames after the mesh arrived (the caller hides the panel and overlay).
export async function capture(page, file) {
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  // A loaded machine can hold a software-GL frame back for long: wait, as for the replies.
  await page.screenshot({ path: file, timeout: 300_000 });
}

// `mtlod-eval score`: the candidate picture against the reference (FIDELITY.md's foveated error and
// the rest), the eye at `focus` (normalised) when given.
export function score(evalBinary, reference, candidate, fovDeg, focus) {
  const out = execFileSync(evalBinary, ['score', reference, candidate, '--fov', String(fovDeg), '--background', kBackground,
                                        ...(focus ? ['--focus', focus.join(',')] : [])], { encoding: 'utf8' });
  return JSON.parse(out);
}

// The input (a pixel bound, a budget...) whose reply has targetBytes within `tolerance`: secant
// steps on log(bytes) against log(input), the slope `guess` until two tries exist, then measured and
// clamped to [min, max]; `limit` keeps each next input in range; a next input the tries already
// hold (`same`) means the bytes saturated. tryAt(input) resolves to a reply with `bytes`. Resolves to
// { input, reply, steps }: the closest try when none gets there (asked again unless it was the last).
export async function atBytes(tryAt, targetBytes, start, { steps, tolerance, slope, limit,
                                                           same = (a, b) => Math.abs(a / b - 1) < 1e-3 }) {
  const tries = [];
  let input = start;
  for (let step = 0; step < steps; ++step) {
    const reply = await tryAt(input);
    tries.push({ input, reply });
    if (Math.abs(reply.bytes / targetBytes - 1) < tolerance) return { input, reply, steps: tries.length };
    let s = slope.guess;
    if (tries.length >= 2) {
      const [a, b] = tries.slice(-2);
      const measured = Math.log(b.reply.bytes / a.reply.bytes) / Math.log(b.input / a.input);
      if (Number.isFinite(measured)) s = Math.min(slope.max, Math.max(slope.min, measured));
    }
    input = limit(input * (targetBytes / reply.bytes) ** (1 / s));
    if (tries.some((t) => same(t.input, input))) break;
  }
  const best = tries.reduce((a, b) => (Math.abs(Math.log(b.reply.bytes / targetBytes)) <
                                       Math.abs(Math.log(a.reply.bytes / targetBytes)) ? b : a));
  if (best === tries.at(-1)) return { input: best.input, reply: best.reply, steps: tries.length };
  return { input: best.input, reply: await tryAt(best.input), steps: tries.length + 1 };
}
