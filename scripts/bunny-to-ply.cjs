// Writes the npm package `bunny` (positions and cells as JS arrays) as an ASCII PLY file.
// Numbers are printed with JavaScript's shortest round-trip form, so every source decimal reads
// back exactly as float32 as it did in the package.
'use strict';
const fs = require('fs');
const path = require('path');

const out = process.argv[2];
if (!out) {
  console.error('usage: node bunny-to-ply.cjs OUT.ply');
  process.exit(2);
}
const bunny = require(path.join(__dirname, 'node_modules', 'bunny'));
const lines = [
  'ply', 'format ascii 1.0', 'comment Stanford Bunny from the npm package bunny (Stanford 3D Scanning Repository)',
  `element vertex ${bunny.positions.length}`, 'property float x', 'property float y', 'property float z',
  `element face ${bunny.cells.length}`, 'property list uchar int vertex_indices', 'end_header',
];
for (const p of bunny.positions) lines.push(`${p[0]} ${p[1]} ${p[2]}`);
for (const c of bunny.cells) lines.push(`${c.length} ${c.join(' ')}`);
fs.writeFileSync(out + '.tmp', lines.join('\n') + '\n');
fs.renameSync(out + '.tmp', out);
