// The numbers and the report of the viewer study (viewer_study.mjs): every setting's foveated error
// at equal bytes, the winners per use, the viewer default against the best setting at its bytes,
// and the agreement of the viewer's pixels with the internal renderer's (mtlod-eval image).
import fs from 'node:fs';
import path from 'node:path';

const geoMean = (xs) => Math.exp(xs.reduce((s, x) => s + Math.log(x), 0) / xs.length);
const mean = (xs) => xs.reduce((s, x) => s + x, 0) / xs.length;
const groupBy = (xs, key) => xs.reduce((m, x) => m.set(key(x), [...(m.get(key(x)) ?? []), x]), new Map());

// A setting's foveated error at `bytes`, from its cuts (same mesh, camera and use): piecewise linear in
// log error against log bytes; beyond the cuts, the nearest segment's slope (a lone cut: slope −1,
// error inversely proportional to bytes, the usual local slope), clamped to [−3, 0].
export function errorAt(points, bytes) {
  const p = [...points].sort((a, b) => a.bytes - b.bytes);
  const lx = Math.log(bytes);
  if (p.length === 1) return p[0].foveated_error * (p[0].bytes / bytes);
  let i = p.findIndex((q) => q.bytes >= bytes);
  i = i < 0 ? p.length - 1 : Math.max(1, i);
  const [a, b] = [p[i - 1], p[i]];
  const ax = Math.log(a.bytes), bx = Math.log(b.bytes), ay = Math.log(a.foveated_error), by = Math.log(b.foveated_error);
  let slope = bx === ax ? -1 : (by - ay) / (bx - ax);
  if (bytes < a.bytes || bytes > b.bytes) slope = Math.min(0, Math.max(-3, slope));
  const [x0, y0] = bytes < a.bytes ? [ax, ay] : bytes > b.bytes ? [bx, by] : [ax, ay];
  return Math.exp(y0 + slope * (lx - x0));
}

// Spearman's rank correlation (average ranks for ties).
export function spearman(xs, ys) {
  const rank = (v) => {
    const order = v.map((x, i) => [x, i]).sort((a, b) => a[0] - b[0]);
    const r = new Array(v.length);
    for (let i = 0; i < order.length;) {
      let j = i;
      while (j + 1 < order.length && order[j + 1][0] === order[i][0]) ++j;
      for (let k = i; k <= j; ++k) r[order[k][1]] = (i + j) / 2;
      i = j + 1;
    }
    return r;
  };
  const rx = rank(xs), ry = rank(ys), mx = mean(rx), my = mean(ry);
  let sxy = 0, sxx = 0, syy = 0;
  for (let i = 0; i < rx.length; ++i) sxy += (rx[i] - mx) * (ry[i] - my), sxx += (rx[i] - mx) ** 2, syy += (ry[i] - my) ** 2;
  return sxx && syy ? sxy / Math.sqrt(sxx * syy) : NaN;
}

// Per use and level: every setting's error at the level's target bytes, relative to the best setting
// of that case; geometric means over the cases.
function rankSettings(records, use, levels, allNames) {
  const settingNames = allNames.filter((n) => records.some((r) => r.use === use && r.setting === n));
  const cases = groupBy(records.filter((r) => r.use === use && r.level >= 0), (r) => `${r.mesh}|${r.camera}`);
  const rows = Object.fromEntries(settingNames.map((n) => [n, { levels: levels.map(() => []), errors: levels.map(() => []) }]));
  for (const cuts of cases.values()) {
    levels.forEach((_, level) => {
      const target = cuts.find((r) => r.level === level)?.target_bytes;
      if (!target) return;
      const errors = settingNames.map((n) => errorAt(cuts.filter((r) => r.setting === n), target));
      const best = Math.min(...errors);
      settingNames.forEach((n, i) => { rows[n].levels[level].push(errors[i] / best); rows[n].errors[level].push(errors[i]); });
    });
  }
  const table = settingNames.map((n) => ({
    setting: n, perLevel: rows[n].levels.map(geoMean), meanError: rows[n].errors.map(mean),
    overall: geoMean(rows[n].levels.flat()), wins: rows[n].levels.flat().filter((x) => x === 1).length,
    cases: rows[n].levels.flat().length,
  }));
  return table.sort((a, b) => a.overall - b.overall);
}

// Each default cut's error over the best setting's at the default cut's bytes.
function defaultRatios(records, use, allNames, isDefault) {
  const settingNames = allNames.filter((n) => records.some((r) => r.use === use && r.setting === n));
  const ratios = [];
  for (const cuts of groupBy(records.filter((r) => r.use === use), (r) => `${r.mesh}|${r.camera}`).values()) {
    const d = cuts.find(isDefault);
    if (!d) continue;
    const best = Math.min(...settingNames.map((n) => errorAt(cuts.filter((r) => r.setting === n && r.level >= 0), d.bytes)));
    ratios.push({ mesh: d.mesh, camera: d.camera, bytes: d.bytes, ratio: d.foveated_error / best });
  }
  const perMesh = [...groupBy(ratios, (r) => r.mesh)].map(([mesh, rs]) => ({ mesh, ratio: geoMean(rs.map((r) => r.ratio)),
                                                                           max: Math.max(...rs.map((r) => r.ratio)),
                                                                           bytes: mean(rs.map((r) => r.bytes)) }));
  return { ratios, perMesh, geoMean: geoMean(ratios.map((r) => r.ratio)), worst: Math.max(...perMesh.map((m) => m.ratio)) };
}

function agreement(records, settingNames) {
  const both = records.filter((r) => Number.isFinite(r.internal_foveated_error) && r.level >= 0);
  if (!both.length) return null;
  const within = [...groupBy(both, (r) => `${r.mesh}|${r.camera}|${r.use}|${r.level}`).values()]
    .filter((g) => g.length > 2).map((g) => spearman(g.map((r) => r.foveated_error), g.map((r) => r.internal_foveated_error)));
  // Method scores of the two studies on these cuts: each setting's geometric-mean error relative to
  // the mean over settings of its case, by the viewer's pixels and by the internal renderer's.
  const score = (key) => settingNames.map((n) => geoMean([...groupBy(both, (r) => `${r.mesh}|${r.camera}|${r.use}|${r.level}`).values()]
    .map((g) => (g.find((r) => r.setting === n)?.[key] ?? NaN) / geoMean(g.map((r) => r[key]))).filter(Number.isFinite)));
  const viewer = score('foveated_error'), internal = score('internal_foveated_error');
  return {
    cuts: both.length, pooled: spearman(both.map((r) => r.foveated_error), both.map((r) => r.internal_foveated_error)),
    withinCase: mean(within.filter(Number.isFinite)), cases: within.length, methods: spearman(viewer, internal),
    viewer, internal, sameTriangles: both.filter((r) => r.internal_triangles === r.triangles).length,
    ratio: geoMean(both.map((r) => r.foveated_error / r.internal_foveated_error)),
  };
}

export function analyse(records, { levelsPx, reference, uses }) {
  const settingNames = [...new Set(records.filter((r) => r.level >= 0).map((r) => r.setting))];
  const ranking = Object.fromEntries(uses.map((u) => [u, rankSettings(records, u, levelsPx, settingNames)]));
  const defaultRatio = defaultRatios(records, 'pointer', settingNames, (r) => r.setting === 'viewer default');
  // levelsPx is the same in every run of the study; the CLI's default is 1 px.
  const level1 = levelsPx.indexOf(1);
  const cliRatio = uses.includes('centre') && level1 >= 0
    ? defaultRatios(records, 'centre', settingNames, (r) => r.setting === reference && r.level === level1) : null;
  return { settingNames, ranking, defaultRatio, cliRatio, agreement: agreement(records, settingNames), levelsPx };
}

const f3 = (x) => (Number.isFinite(x) ? x.toFixed(3) : '–');
const f4 = (x) => (Number.isFinite(x) ? x.toFixed(4) : '–');

function csv(records) {
  const keys = ['mesh', 'camera', 'use', 'setting', 'level', 'level_px', 'target_bytes', 'px', 'bytes', 'triangles', 'steps',
                'full_triangles', 'foveated_error', 'ssim', 'foveated_mae', 'internal_foveated_error', 'internal_triangles'];
  return [keys.join(','), ...records.map((r) => keys.map((k) => (k === 'setting' ? `"${r[k]}"` : r[k] ?? '')).join(','))].join('\n') + '\n';
}

export function writeReport(o) {
  const a = o.analysis, md = [];
  const add = (...lines) => md.push(...lines);
  const uses = { pointer: 'viewer and mtlod-gaze (the pointer or gaze sample is the focus; the eye is scored there)',
                 centre: 'mtlod-client / mtlod-extract without --focus (the view\'s centre is the focus; the eye is scored on the model\'s centroid)' };
  add('# Fidelity on the viewer\'s own pixels', '',
      `Generated by \`${o.command}\` in ${Math.round(o.seconds)} s${(o.also ?? []).map((x) => `, \`${x.command}\` in ${Math.round(x.seconds)} s (the \`${x.uses.join(', ')}\` use, ${x.meshes.length} meshes × ${x.cameraCount} cameras, ${Object.keys(x.settings).length} settings${x.label ? `; its meshes named “… ${x.label}”` : ''})`).join('')}${o.also?.length ? ', joined by `node tests/evaluation/viewer_study.mjs --report-only --work DIR --also-work DIR2[:LABEL]... --out tests/evaluation`' : ''}. Do not edit by hand.`, '',
      '## Setup', '',
      `- The real viewer page (\`clients/web/index.html\`, \`viewer.js\`) in headless Debian Chromium (SwiftShader software GL), ${o.size.width}×${o.size.height}, against a real \`mtlod-server\` over \`/ws\`; every cut is what the page shows after the reply to a request it made itself, its criteria set through the panel's controls (delta updates off, so every reply is a whole mesh and its bytes the cut's payload: Draco edgebreaker with normals, as the page asks).`,
      `- ${o.meshes.length} meshes (${o.meshes.map((m) => `\`${path.basename(m)}\``).join(', ')}), ${o.cameraCount} orbit cameras each (mtlod-eval's: azimuth every ${360 / o.cameraCount}°, elevation +25° and −10° in turn, 40° vertical field of view, the bounding sphere filling 90 % of it).`,
      '- Reference: the full model drawn by the same page (error 0, no budget: the whole Multi-Tessellation). Score: `mtlod-eval score` (core/eval/image_metrics), the **foveated error** 1 − foveated SSIM of FIDELITY.md on the page\'s pixels: covered = differs from the page\'s background #202428 in either picture, acuity e2/(e2 + e), e2 = 2.3°, the eye at the camera\'s centre of projection, focused on the centroid of the full model\'s picture.',
      `- Equal bytes: three payload levels per (mesh, camera, use), the bytes \`${a.settingNames[0]}\` (today's default criteria, no budget) sends at ${a.levelsPx.join(', ')} px; every other setting's pixel bound found by secant steps on its reply's bytes (within 3 %, at most 7 steps), its error at the exact level read off its three cuts (log–log).`,
      `- Uses: ${Object.entries(uses).map(([u, t]) => `**${u}**: ${t}`).join('; ')}.`,
      `- The viewer's defaults as the page opens: ${Object.entries(o.defaults ?? {}).map(([k, v]) => `${k} ${v}`).join(', ')}.`,
      '- Settings (the panel\'s controls; `focus=D/F`: threshold D px, factor F; `sil=D/F` the silhouette band; `hidden=H` the hidden-surface factor; `uniform px`: focus off, the pixel bound everywhere):',
      '');
  for (const [name, s] of Object.entries(o.settings))
    add(`  - **${name}**: falloff ${s.falloff}, focus ${s.focus ? `${s['focus-distance']}/${s['focus-factor']}` : 'off'}, silhouette ${s.silhouette ? `${s['silhouette-distance']}/${s['silhouette-factor']}` : 'off'}, hidden ×${s['hidden-factor']}`);
  for (const note of o.notes ?? []) add(`- ${note}`);
  add('');
  add('## Winners', '', 'Each setting\'s foveated error at equal bytes over the best setting\'s in the same case (mesh, camera, level), geometric mean over the cases (1.000 = best in every case); mean foveated error per level.', '');
  for (const [use, table] of Object.entries(a.ranking)) {
    add(`### ${use}: ${uses[use]}`, '', `| setting | ${a.levelsPx.map((p) => `/ best at ${p} px bytes`).join(' | ')} | all levels | best in | ${a.levelsPx.map((p) => `error at ${p} px bytes`).join(' | ')} |`,
        `| --- | ${a.levelsPx.map(() => '---:').join(' | ')} | ---: | ---: | ${a.levelsPx.map(() => '---:').join(' | ')} |`);
    for (const r of table)
      add(`| ${r === table[0] ? `**${r.setting}**` : r.setting} | ${r.perLevel.map(f3).join(' | ')} | ${f3(r.overall)} | ${r.wins}/${r.cases} | ${r.meanError.map(f4).join(' | ')} |`);
    add('');
  }
  const d = a.defaultRatio;
  add('## The viewer\'s default cut against the best setting at its bytes', '',
      'The page as it opens (pointer on the model), each camera\'s cut scored, over the lowest error any setting reaches at the same bytes (its curve read at those bytes). Target: within 1.2×.', '',
      '| mesh | mean bytes | default / best (geo-mean) | worst camera |', '| --- | ---: | ---: | ---: |');
  for (const m of d.perMesh) add(`| ${m.mesh} | ${Math.round(m.bytes)} | ${f3(m.ratio)} | ${f3(m.max)} |`);
  add(`| **all** | | **${f3(d.geoMean)}** | ${f3(Math.max(...d.ratios.map((r) => r.ratio)))} |`, '',
      `Target ${d.geoMean <= 1.2 && d.worst <= 1.2 ? '**met**' : '**not met**'}: overall ${f3(d.geoMean)}, worst mesh ${f3(d.worst)}.`, '');
  if (a.cliRatio)
    add(`The CLI's default (the same criteria at 1 px, focus at the view's centre; use \`centre\`) over the best at its bytes: ${f3(a.cliRatio.geoMean)} (worst mesh ${f3(a.cliRatio.worst)}).`, '');
  const g = a.agreement;
  if (g) {
    add('## Agreement with the internal renderer', '',
        `The cuts of the first ${o.agreementCameras} cameras of every mesh made again by \`mtlod-extract\` from the same MT with the page's request as flags, drawn by the internal renderer and scored by \`mtlod-eval image\` (FIDELITY.md's pictures: white background, headlight Lambert) at the same camera, size and focus. ${g.sameTriangles} of ${g.cuts} cuts have the same triangle count as the page's (the page's camera matrices are float32).`, '',
        `- Rank correlation (Spearman) of the two foveated errors over all ${g.cuts} cuts: **${f3(g.pooled)}**; within a case (the settings at one mesh, camera, use and level; ${g.cases} cases), mean: **${f3(g.withinCase)}**.`,
        `- The settings' scores (geometric mean over the cases of error / the case's geometric mean), viewer against internal: Spearman **${f3(g.methods)}**.`,
        `- Viewer error / internal error, geometric mean: ${f3(g.ratio)} (the page's dark background, hemisphere light and antialiasing make each picture's numbers differ; the order is what the studies share).`, '',
        '| setting | viewer score | internal score |', '| --- | ---: | ---: |');
    a.settingNames.forEach((n, i) => add(`| ${n} | ${f3(g.viewer[i])} | ${f3(g.internal[i])} |`));
    add('');
  }
  add('Raw numbers for every cut: [`viewer.csv`](viewer.csv).');
  fs.writeFileSync(path.join(o.out, 'VIEWER.md'), `${md.join('\n')}\n`);
  fs.writeFileSync(path.join(o.out, 'viewer.csv'), csv(o.records));
  updateFidelity(o, a);
}

// FIDELITY.md (mtlod-eval fidelity's report) ends with this study's summary, from its marker line
// to the end of the file: replaced here on every run, kept by mtlod-eval fidelity when it rewrites
// its own part.
function updateFidelity(o, a) {
  const file = path.join(o.out, 'FIDELITY.md');
  if (!fs.existsSync(file)) return;
  const marker = '<!-- viewer-study: written by tests/evaluation/viewer_study.mjs; do not edit -->';
  const text = fs.readFileSync(file, 'utf8');
  const at = text.indexOf('<!-- viewer-study:');
  const kept = (at < 0 ? text : text.slice(0, at)).trimEnd();
  const pointer = a.ranking.pointer ?? Object.values(a.ranking)[0];
  const winner = pointer[0], def = pointer.find((r) => r.setting === a.settingNames[0]);
  const g = a.agreement;
  const lines = [marker, '', '## On the viewer\'s own pixels', '',
    `[VIEWER.md](VIEWER.md) runs the same comparison on what the browser viewer shows: the real page in headless Chromium (software GL, ${o.size.width}×${o.size.height}) against the real server, ${o.meshes.length} meshes, up to ${o.cameraCount} cameras each, ${a.settingNames.length} criteria settings set through the page's panel at three equal-byte levels (the bytes today's default sends at ${a.levelsPx.join(', ')} px), scored by the same foveated error (\`mtlod-eval score\`, core/eval/image_metrics) against the full model drawn by the page.`,
    '',
    `- Best setting, pointer as focus: **${winner.setting}** (error / best at equal bytes ${f3(winner.overall)}, geometric mean; best in ${winner.wins}/${winner.cases} cases); this report's default criteria \`${a.settingNames[0]}\`: ${f3(def?.overall)}.`,
    `- The viewer's default cut (as the page opens) over the best setting at its bytes: ${f3(a.defaultRatio.geoMean)} (worst mesh ${f3(a.defaultRatio.worst)}; target 1.2).`];
  if (g)
    lines.push(`- Agreement with this report's renderer on the same cuts (${g.cuts}, made again by \`mtlod-extract\` and drawn by \`mtlod-eval image\`): Spearman ${f3(g.pooled)} over all cuts, ${f3(g.withinCase)} among the settings of one case on average, ${f3(g.methods)} between the settings' overall scores. The pictures differ (dark background and two lights in the page, white and a headlight here), so absolute errors differ by ${f3(g.ratio)}× on average; the orders are what carry over.`);
  // Screenshots of the page as it opens (viewer_screenshots.mjs --name viewer-dragon..., the pointer on
  // the model), when they are there.
  // The one named -before is the page of an older commit (--as-opened), shown after them.
  const figures = fs.existsSync(path.join(o.out, 'figures')) ? fs.readdirSync(path.join(o.out, 'figures')) : [];
  const shots = figures.filter((f) => /^viewer-dragon-(flat|smooth)\.png$/.test(f)).sort();
  if (shots.length)
    lines.push('', '### The viewer at its defaults', '',
               'The 871k dragon at 1280×720, the pointer on the model (`tests/evaluation/viewer_screenshots.mjs`): `smooth` is how it opens, shaded with the normals its payload carries; `flat` is the same cut with the flat-shading toggle, which shows its facets (without normals the page could draw nothing else).', '',
               ...shots.map((f) => `![${f}](figures/${f})`));
  if (shots.length && figures.includes('viewer-dragon-before.png'))
    lines.push('', 'Before: the same page and camera at commit `229baa4`, as it opened with its defaults (4,556 triangles, 11,448 bytes; flat facets, since its payloads carried no normals), taken with `--as-opened` from that commit\'s server and web root:', '',
               '![viewer-dragon-before.png](figures/viewer-dragon-before.png)');
  fs.writeFileSync(file, `${kept}\n\n${lines.join('\n')}\n`);
}
