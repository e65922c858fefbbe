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
