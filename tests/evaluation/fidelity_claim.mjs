// Checks the claim of an `mtlod-eval fidelity` report (its "Targets" table) against the run's own raw
// numbers. From the csv, every equal-bytes case (mesh, budget, camera) is scored again: the target
// method against each peer (1 − foveated SSIM, peer over target). Then:
//   - the wins (cases where the target beats every peer) and the geometric means of the ratios must
//     be what the report's **all** row states;
//   - they must meet the claim: at least --min-share of the cases won, every geometric mean at least
//     --min-ratio;
//   - with --stated REPORT (e.g. the committed tests/evaluation/FIDELITY.md), every (mesh, budget) row
//     of the run must appear there with the same cases won and the same ratios (within 0.02: the two
//     runs may be different builds, whose floating point differs in the last bits).
//
// node tests/evaluation/fidelity_claim.mjs --dir DIR [--report FIDELITY.md] [--csv fidelity.csv]
//     [--target default] [--peers uniform,meshopt] [--cases N] [--min-share 0.9] [--min-ratio 1.5]
//     [--stated REPORT]
//
// --cases: the number of equal-bytes cases the run must have (meshes × budgets × cameras), so that a
// run that skipped its budgets cannot pass. Exits 0 when everything holds, 1 otherwise (each problem
// named), 2 on a bad command line or unreadable files.
import fs from 'node:fs';
import path from 'node:path';

const args = {};
for (let i = 2; i < process.argv.length; i += 2) {
  const key = process.argv[i];
  if (!key.startsWith('--') || i + 1 >= process.argv.length) {
    console.error(`fidelity_claim: cannot read '${key}' (options are --name value)`);
    process.exit(2);
  }
  args[key.slice(2)] = process.argv[i + 1];
}
if (!args.dir) {
  console.error('fidelity_claim: --dir is required');
  process.exit(2);
}
const target = args.target ?? 'default';
const peers = (args.peers ?? 'uniform,meshopt').split(',');
const minShare = Number(args['min-share'] ?? 0.9), minRatio = Number(args['min-ratio'] ?? 1.5);
const read = (file) => {
  try {
    return fs.readFileSync(file, 'utf8');
  } catch (e) {
    console.error(`fidelity_claim: ${e.message}`);
    process.exit(2);
  }
};
const csvText = read(path.join(args.dir, args.csv ?? 'fidelity.csv'));
const report = read(path.join(args.dir, args.report ?? 'FIDELITY.md'));
const problems = [];

// The "Targets" table of a report: its peer columns ("uniform / default", ...), its rows by
// "mesh budget" (cases won "K/N" and the ratios), and its **all** row.
function targetsTable(text, name) {
  const lines = text.split('\n');
  const start = lines.findIndex((l) => l.startsWith('| mesh | budget | bytes | cases won |'));
  if (start < 0) return problems.push(`${name} has no Targets table`), null;
  const columns = lines[start].split(' | ').slice(4, -1).map((c) => c.replace(/ \(geo-mean\)$/, ''));
  const rows = new Map();
  let all = null;
  for (const line of lines.slice(start + 2)) {
    if (!line.startsWith('|')) break;
    const cells = line.split('|').slice(1, -1).map((c) => c.trim().replace(/\*\*/g, ''));
    const ratios = cells.slice(4, 4 + columns.length).map(Number);
    const won = cells[3].replace(/ \(.*\)$/, '');
    if (cells[0] === 'all') all = { won, ratios };
    else rows.set(`${cells[0]} ${cells[1]}`, { won, ratios });
  }
  if (!all) problems.push(`${name}'s Targets table has no **all** row`);
  return { columns, rows, all };
}

// The raw numbers: the foveated error of every method in every equal-bytes case.
const [header, ...lines] = csvText.trim().split('\n');
const names = header.split(',');
const cases = new Map();
for (const line of lines) {
  const row = Object.fromEntries(line.split(',').map((value, i) => [names[i], value]));
  if (row.equal !== 'bytes') continue;
  const key = `${row.mesh} ${row.budget}`;
  if (!cases.has(key)) cases.set(key, new Map());
  if (!cases.get(key).has(row.camera)) cases.get(key).set(row.camera, {});
  cases.get(key).get(row.camera)[row.method] = 1 - Number(row.foveated_ssim);
}

// Wins and geometric means over a list of cases, as fidelity.cpp computes them (a zero error counts
// as 1e-12).
function score(errorsList, label) {
  let won = 0;
  const logs = peers.map(() => []);
  for (const errors of errorsList) {
    let all = true;
    peers.forEach((peer, p) => {
      if (!(peer in errors) || !(target in errors)) return problems.push(`${label}: no ${peer} or ${target} row`);
      const ratio = errors[peer] / Math.max(1e-12, errors[target]);
      logs[p].push(Math.log(ratio));
      all &&= ratio > 1;
    });
    won += all;
  }
  const ratios = logs.map((v) => (v.length ? Math.exp(v.reduce((s, x) => s + x, 0) / v.length) : 0));
  return { won, n: errorsList.length, ratios };
}
const perRow = new Map([...cases].map(([key, cameras]) => [key, score([...cameras.values()], key)]));
const total = score([...cases.values()].flatMap((cameras) => [...cameras.values()]), 'all');
if (args.cases !== undefined && total.n !== Number(args.cases))
  problems.push(`${total.n} equal-bytes cases in the csv, expected ${args.cases}`);

// The report's rows and its **all** row against the csv; the report rounds to two decimals from
// unrounded scores, the csv has six: one unit of the last decimal is allowed.
const compare = (table, key, computed, tolerance, name) => {
  const stated = key === 'all' ? table.all : table.rows.get(key);
  if (!stated) return problems.push(`${name} has no row for ${key}`);
  if (stated.won !== `${computed.won}/${computed.n}`)
    problems.push(`${name} states ${stated.won} cases won for ${key}, the csv gives ${computed.won}/${computed.n}`);
  peers.forEach((peer, p) => {
    const column = table.columns.indexOf(`${peer} / ${target}`);
    if (column < 0) return problems.push(`${name} has no '${peer} / ${target}' column`);
    if (!(Math.abs(stated.ratios[column] - computed.ratios[p]) <= tolerance))
      problems.push(`${name} states ${peer}/${target} ${stated.ratios[column]} for ${key}, ` +
                    `the csv gives ${computed.ratios[p].toFixed(4)}`);
  });
};
const own = targetsTable(report, 'the report');
if (own) {
  for (const [key, computed] of perRow) compare(own, key, computed, 0.0101, 'the report');
  if (own.all) compare(own, 'all', total, 0.0101, 'the report');
}
if (args.stated) {
  const stated = targetsTable(read(args.stated), args.stated);
  if (stated) for (const [key, computed] of perRow) compare(stated, key, computed, 0.02, args.stated);
}

// The claim itself.
if (!(total.n > 0 && total.won >= minShare * total.n))
  problems.push(`${target} wins ${total.won}/${total.n} cases, fewer than ${100 * minShare} %`);
peers.forEach((peer, p) => {
  if (!(total.ratios[p] >= minRatio))
    problems.push(`${peer}/${target} ${total.ratios[p].toFixed(4)} (geometric mean) is below ${minRatio}`);
});

const summary = `${target} at equal bytes: ${total.won}/${total.n} cases won; ` +
                peers.map((peer, p) => `${peer}/${target} ${total.ratios[p].toFixed(4)}`).join('; ');
if (problems.length) {
  console.log(`fidelity_claim: ${summary}`);
  for (const problem of problems) console.log(`fidelity_claim: ${problem}`);
  process.exit(1);
}
console.log(`fidelity_claim: ${summary}; ${args.stated ? `the report and ${args.stated} state` : 'the report states'} the same, ` +
            `and it meets ${100 * minShare} % and ${minRatio}×`);
