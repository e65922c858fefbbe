// What the browser tests (viewer_test.mjs, viewer_codecs_test.mjs, gltf_three_test.mjs), the viewer
// study and the decode benchmark share: the repository root, playwright-core from scripts/node_modules,
// `--name value` arguments, Debian's Chromium or a skip (exit 77, which ctest reports as skipped) and the
// flags it runs with, starting a server and waiting for its port file, comparing two screenshots, and
// ok/FAIL lines counted for the exit status.
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import { createRequire } from 'node:module';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

export const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');
export const { chromium } = createRequire(path.join(root, 'scripts/package.json'))('playwright-core');

// `--name value` pairs into an object (flags without a value are left to the caller); `--out` is
// created.
export function parseArgs(argv, required, flags = []) {
  const args = Object.fromEntries(argv.filter((a) => !flags.includes(a)).reduce((pairs, a, i, all) =>
    (a.startsWith('--') ? [...pairs, [a.slice(2), all[i + 1]]] : pairs), []));
  for (const name of required) {
    if (!args[name]) throw new Error(`missing --${name}`);
  }
  if (args.out) fs.mkdirSync(args.out, { recursive: true });
  return args;
}

// The Chromium binary (MTLOD_CHROMIUM overrides it); exits 77 when it is not installed.
export function chromiumOrSkip() {
  const chromiumPath = process.env.MTLOD_CHROMIUM ?? '/usr/bin/chromium';
  if (!fs.existsSync(chromiumPath)) {
    console.log(`skipped: ${chromiumPath} is not installed (scripts/bootstrap.sh installs Debian's chromium)`);
    process.exit(77);
  }
  return chromiumPath;
}

// Headless Chromium with software GL (SwiftShader) and none of its background network traffic.
export const chromiumArgs = ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
                             '--disable-background-networking', '--disable-component-update', '--disable-sync',
                             '--use-angle=swiftshader', '--enable-unsafe-swiftshader'];

export const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

// The HTTP port an mtlod-server started with --port-file writes on its second line, polled every
// 100 ms up to `attempts` times while `running()` holds; 0 when it never came.
export async function waitForHttpPort(portFile, running, attempts) {
  for (let i = 0; i < attempts && running(); ++i) {
    const lines = fs.existsSync(portFile) ? fs.readFileSync(portFile, 'utf8').trim().split('\n') : [];
    if (lines.length >= 2) return Number(lines[1]);
    await sleep(100);
  }
  return 0;
}

export const results = { failures: 0 };
export function check(condition, message) {
  console.log(`${condition ? 'ok  ' : 'FAIL'} ${message}`);
  if (!condition) results.failures += 1;
}

// An mtlod-server on OS-chosen ports (its port file and log in `out`, named after `name`), serving
// HTTP from this tree (--web-root: the viewer under test is this checkout's, whichever build the binary
// comes from): { child, httpPort (0 when it did not start), exit ({code, signal} once it has exited), stop() }.
// stop() sends SIGTERM and waits up to 10 s for the drain; it resolves to the exit, or null.
export async function startServer(binary, serverArgs, out, name) {
  const portFile = path.join(out, `${name}-ports`);
  fs.rmSync(portFile, { force: true });
  const log = fs.openSync(path.join(out, `${name}-server.log`), 'w');
  const child = spawn(binary, [...serverArgs, '--cache-dir', out, '--port', '0', '--http-port', '0', '--port-file', portFile,
                               '--web-root', root, '--workers', '2', '--log-level', 'info'],
                      { stdio: ['ignore', log, log] });
  const server = { child, exit: null, httpPort: 0 };
  child.on('exit', (code, signal) => { server.exit = { code, signal }; });
  server.stop = async () => {
    if (!server.exit) {
      child.kill('SIGTERM');
      for (let i = 0; i < 200 && !server.exit; ++i) await sleep(50);
    }
    return server.exit;
  };
  server.httpPort = await waitForHttpPort(portFile, () => !server.exit, 600);
  return server;
}

// The end of a test of startServer's server: the browser closed, the server stopped and checked to have
// drained and exited cleanly (killed if it did not), the deadline timer cleared; exits with the status
// of the checks.
export async function finish({ browser, server, deadline }) {
  if (browser) await browser.close();
  if (server) {
    const exit = await server.stop();
    check(exit && exit.code === 0, `the server drained and exited cleanly (${JSON.stringify(exit)})`);
    if (!exit) server.child.kill('SIGKILL');
  }
  clearTimeout(deadline);
  process.exit(results.failures ? 1 : 0);
}

// Two PNG pictures (Buffers) compared pixel by pixel in `page` (any page of a running Chromium, which
// decodes them): { pixels, meanDifference (mean over pixels and RGB channels, 0..255), over (pixels whose
// largest channel difference exceeds `threshold`), covered (pixels of `a` not of the colour
// `background`, [r, g, b]) }. Pictures of different sizes are an Error.
export async function comparePictures(page, a, b, threshold, background) {
  return page.evaluate(async ({ a, b, threshold, background }) => {
    const pixels = async (base64) => {
      const bitmap = await createImageBitmap(await (await fetch(`data:image/png;base64,${base64}`)).blob());
      const canvas = new OffscreenCanvas(bitmap.width, bitmap.height);
      const context = canvas.getContext('2d');
      context.drawImage(bitmap, 0, 0);
      return context.getImageData(0, 0, bitmap.width, bitmap.height);
    };
    const [pa, pb] = [await pixels(a), await pixels(b)];
    if (pa.width !== pb.width || pa.height !== pb.height) {
      throw new Error(`pictures of ${pa.width}x${pa.height} and ${pb.width}x${pb.height}`);
    }
    let sum = 0, over = 0, covered = 0;
    for (let i = 0; i < pa.data.length; i += 4) {
      let largest = 0, away = 0;
      for (let k = 0; k < 3; ++k) {
        const d = Math.abs(pa.data[i + k] - pb.data[i + k]);
        sum += d;
        largest = Math.max(largest, d);
        away = Math.max(away, Math.abs(pa.data[i + k] - background[k]));
      }
      if (largest > threshold) over += 1;
      if (away > 2) covered += 1;
    }
    const count = pa.width * pa.height;
    return { pixels: count, meanDifference: sum / (3 * count), over, covered };
  }, { a: a.toString('base64'), b: b.toString('base64'), threshold, background });
}
