// Screenshots of the viewer as a person first sees it: the real page (clients/web/) in headless
// Debian Chromium at 1280×720 with its default criteria, the pointer held on the model, once
// smooth-shaded (the default) and once with the flat-shading toggle. The figures of FIDELITY.md,
// "The viewer at its defaults".
//
// node tests/evaluation/viewer_screenshots.mjs --url http://127.0.0.1:8080/?model=dragon-871k \
//     --out tests/evaluation/figures [--name viewer-dragon] [--x 0.55 --y 0.45] [--as-opened]
// --as-opened takes one screenshot, NAME.png, touching no control: for a page from an older commit
// (the figure "before"), which has no shading toggle.
import path from 'node:path';
import { chromium, chromiumArgs, chromiumOrSkip, parseArgs } from '../clients/browser_support.mjs';

const args = parseArgs(process.argv.slice(2), ['url', 'out'], ['--as-opened']);
const asOpened = process.argv.includes('--as-opened');
const name = args.name ?? 'viewer';
const pointer = [Number(args.x ?? 0.55), Number(args.y ?? 0.45)];
const size = { width: 1280, height: 720 };

const browser = await chromium.launch({
  executablePath: chromiumOrSkip(),
  args: chromiumArgs,
});
try {
  const page = await browser.newPage({ viewport: size });
  await page.goto(args.url);
  await page.waitForFunction(() => window.mtlod && window.mtlod.meshes > 0, null, { timeout: 60_000 });
  // The pointer is the focus: wait for the mesh refined around it.
  await page.mouse.move(size.width * pointer[0], size.height * pointer[1]);
  await page.waitForFunction((want) => {
    const r = window.mtlod.lastReply;
    return r && r.focus && Math.abs(r.focus[0] - want[0]) < 0.01 && Math.abs(r.focus[1] - want[1]) < 0.01;
  }, pointer, { timeout: 60_000 });
  await page.waitForTimeout(500);  // frames drawn with the last mesh
  const reply = await page.evaluate(() => window.mtlod.lastReply);
  if (asOpened) {
    const file = path.join(args.out, `${name}.png`);
    await page.screenshot({ path: file });
    console.log(`${file}: ${reply.triangles} triangles, ${reply.bytes} bytes, as the page opened`);
  }
  for (const flat of asOpened ? [] : [false, true]) {
    if (flat) {
      await page.check('#flat');
      await page.waitForTimeout(300);
    }
    const file = path.join(args.out, `${name}-${flat ? 'flat' : 'smooth'}.png`);
    await page.screenshot({ path: file });
    console.log(`${file}: ${reply.triangles} triangles, ${reply.bytes} bytes, ${flat ? 'flat' : 'smooth'} shading`);
  }
} finally {
  await browser.close();
}
