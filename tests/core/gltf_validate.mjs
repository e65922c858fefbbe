// Runs the Khronos glTF validator (npm gltf-validator, in scripts/node_modules) on .glb/.gltf files
// and prints, per file, its counts of errors, warnings, infos and hints and every issue it found.
// Exits 0 when no file has an error or a warning, 1 otherwise, 77 when the validator is not
// installed (scripts/bootstrap.sh installs it).
//
// node gltf_validate.mjs FILE...
import fs from 'node:fs';
import { createRequire } from 'node:module';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');
let validator;
try {
  validator = createRequire(path.join(root, 'scripts/package.json'))('gltf-validator');
} catch (error) {
  console.log(`skipped: npm gltf-validator is not installed in scripts/node_modules (${error.message})`);
  process.exit(77);
}

const files = process.argv.slice(2);
if (files.length === 0) {
  console.log('usage: node gltf_validate.mjs FILE...');
  process.exit(2);
}

const severities = ['error', 'warning', 'info', 'hint'];
let failed = false;
for (const file of files) {
  let report;
  try {
    report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)),
                                           { uri: path.basename(file), maxIssues: 0, writeTimestamp: false });
  } catch (error) {
    // The validator rejects input it cannot even recognise as glTF or GLB.
    console.log(`${file}: not validated: ${error}`);
    failed = true;
    continue;
  }
  const { numErrors, numWarnings, numInfos, numHints, messages } = report.issues;
  console.log(`${file}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos, ${numHints} hints ` +
              `(validator ${report.validatorVersion})`);
  for (const m of messages) {
    console.log(`  ${severities[m.severity] ?? m.severity} ${m.code} at ${m.pointer ?? m.offset ?? '-'}: ${m.message}`);
  }
  if (numErrors > 0 || numWarnings > 0) failed = true;
}
process.exit(failed ? 1 : 0);
