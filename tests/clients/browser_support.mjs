// What the browser tests (viewer_test.mjs, gltf_three_test.mjs) share: the repository root,
// playwright-core from scripts/node_modules, `--name value` arguments, Debian's Chromium or a skip
// (exit 77, which ctest reports as skipped), and ok/FAIL lines counted for the exit status.
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

export const results = { failures: 0 };
export function check(condition, message) {
  console.log(`${condition ? 'ok  ' : 'FAIL'} ${message}`);
  if (!condition) results.failures += 1;
}
