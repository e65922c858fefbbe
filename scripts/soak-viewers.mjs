// Viewers for scripts/soak-fleet.sh: the real viewer page (clients/web) in headless Chromium, one
// page per viewer, each on one model (?model=, as a load balancer routes it), orbiting the camera
// and moving the pointer (the focus) about twice a second. A page whose WebSocket closed (its
// replica was killed) is reloaded, as a person would. Writes a JSON summary: meshes shown, error
// replies by code, disconnections, and decode_errors (anything else the page reported: a payload
// that did not decode, a delta that did not apply, an exception).
//   node scripts/soak-viewers.mjs --port HTTP_PORT --duration SECONDS --models a,b --viewers N --out FILE
import fs from 'node:fs';
import { createRequire } from 'node:module';

const require = createRequire(import.meta.url);
const { chromium } = require('playwright-core');

const args = Object.fromEntries(process.argv.slice(2).reduce((pairs, value, i, all) => {
  if (value.startsWith('--')) pairs.push([value.slice(2), all[i + 1]]);
  return pairs;
}, []));
const port = Number(args.port), duration = Number(args.duration ?? 60), viewers = Number(args.viewers ?? 4);
const models = (args.models ?? '').split(',').filter(Boolean);
const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));

const summary = { viewers, meshes: 0, errors_by_code: {}, disconnects: 0, reloads: 0, decode_errors: 0, details: [] };
const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
         '--disable-component-update', '--disable-sync', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});

// Sorts what a page reported: error replies by code, closed sockets, and everything else.
function classify(text) {
  const code = /^([a-z_]+): /.exec(text)?.[1];
  if (text === 'disconnected' || text.startsWith('no connection')) summary.disconnects += 1;
  else if (code && code !== 'model_info') summary.errors_by_code[code] = (summary.errors_by_code[code] ?? 0) + 1;
  else if (code === 'model_info') {
    const inner = /^model_info: /.test(text) ? 'unknown_model' : code;
    summary.errors_by_code[inner] = (summary.errors_by_code[inner] ?? 0) + 1;
  } else {
    summary.decode_errors += 1;
    if (summary.details.length < 20) summary.details.push(text);
  }
}

async function viewer(index) {
  const model = models[index % models.length];
  const page = await browser.newPage({ viewport: { width: 480, height: 360 } });
  page.on('pageerror', (e) => classify(`page error: ${e.message}`));
  const url = `http://127.0.0.1:${port}/?model=${encodeURIComponent(model)}`;
  let seenErrors = 0, seenMeshes = 0;
  const open = async () => {
    seenErrors = 0;
    seenMeshes = 0;
    try {
      await page.goto(url, { timeout: 15_000 });
    } catch {
      // HAProxy may have no replica up for a moment: the next round reloads.
    }
  };
  await open();
  const until = Date.now() + duration * 1000;
  for (let step = 0; Date.now() < until; ++step) {
    await sleep(500);
    let state;
    try {
      state = await page.evaluate(() => ({ connected: window.mtlod?.connected ?? false,
                                           meshes: window.mtlod?.meshes ?? 0, errors: window.mtlod?.errors ?? [] }));
    } catch {
      state = { connected: false, meshes: 0, errors: [] };
    }
    for (const text of state.errors.slice(seenErrors)) classify(text);
    seenErrors = state.errors.length;
    summary.meshes += Math.max(0, state.meshes - seenMeshes);
    seenMeshes = state.meshes;
    if (!state.connected) {
      summary.reloads += 1;
      await open();
      continue;
    }
    // Orbit a little (drag) and move the focus (the pointer).
    const x = 240 + 150 * Math.cos(step / 7), y = 180 + 100 * Math.sin(step / 5);
    try {
      if (step % 4 === 0) {
        await page.mouse.move(x, y);
        await page.mouse.down();
        await page.mouse.move(x + 25, y + 5, { steps: 3 });
        await page.mouse.up();
      } else {
        await page.mouse.move(x, y);
      }
    } catch {
      // The page is navigating (reload): the next round looks again.
    }
  }
  await page.close();
}

await Promise.all(Array.from({ length: viewers }, (_, i) => viewer(i)));
await browser.close();
fs.writeFileSync(args.out, JSON.stringify(summary, null, 2));
console.log(JSON.stringify(summary));
