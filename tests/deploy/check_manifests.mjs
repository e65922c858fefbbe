// Static checks of docker/: every YAML file parses (strictly: duplicate keys are errors), and the
// files agree with each other and with the server: every mtlod-server flag they pass exists in
// `mtlod-server --help`, every variable docker/haproxy.cfg reads is set by compose.yaml, probes,
// resources and the drain bound are in place, and names referenced across files exist.
//   node tests/deploy/check_manifests.mjs --server build/test/server/mtlod-server
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import { createRequire } from 'node:module';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const root = path.resolve(path.dirname(fileURLToPath(import.meta.url)), '../..');
const YAML = createRequire(path.join(root, 'scripts/package.json'))('yaml');
const serverIndex = process.argv.indexOf('--server');
if (serverIndex < 0) throw new Error('missing --server PATH');
const help = execFileSync(process.argv[serverIndex + 1], ['--help'], { encoding: 'utf8' });

const failures = [];
const check = (ok, message) => { if (!ok) failures.push(message); };
const read = (relative) => fs.readFileSync(path.join(root, relative), 'utf8');
const parseAll = (relative) => {
  const docs = YAML.parseAllDocuments(read(relative), { uniqueKeys: true, merge: true, prettyErrors: true });
  for (const doc of docs) for (const error of doc.errors) failures.push(`${relative}: ${error.message}`);
  return docs.map((d) => d.toJS());
};
// Flags in an argument list ("--flag", "--flag=value") that mtlod-server does not know.
const checkFlags = (where, args) => {
  for (const arg of args) {
    if (typeof arg !== 'string' || !arg.startsWith('--')) continue;
    const flag = arg.split('=')[0];
    check(new RegExp(`\\s${flag}\\b`).test(help), `${where}: mtlod-server has no flag ${flag}`);
  }
};

// ---- compose.yaml and haproxy.cfg ----
const [compose] = parseAll('docker/compose.yaml');
const services = compose.services ?? {};
const replicas = Object.entries(services).filter(([, s]) => s.image === 'mtlod');
check(replicas.length >= 2, `compose.yaml: ${replicas.length} mtlod replicas, want at least 2`);
for (const [name, s] of replicas) {
  checkFlags(`compose.yaml ${name}`, s.command ?? []);
  check((s.volumes ?? []).some((v) => /:\/models:ro$/.test(v)), `compose.yaml ${name}: /models is not mounted read-only`);
  check(/^\d+s$/.test(s.stop_grace_period ?? ''), `compose.yaml ${name}: no stop_grace_period`);
}
const haproxy = services.haproxy;
check(haproxy, 'compose.yaml: no haproxy service');
const cfg = read('docker/haproxy.cfg');
const used = new Set([...cfg.matchAll(/\$\{(MTLOD_[A-Z0-9_]+)\}/g)].map((m) => m[1]));
for (const variable of used) {
  check(haproxy?.environment?.[variable] !== undefined, `compose.yaml: haproxy.cfg reads ${variable}, which haproxy's environment does not set`);
}
for (const [, s] of replicas) {
  const hosts = Object.entries(haproxy?.environment ?? {}).filter(([k]) => /_HOST$/.test(k)).map(([, v]) => v);
  check(hosts.some((h) => s.hostname === h), `compose.yaml: replica ${s.hostname} is not behind haproxy`);
}
check((haproxy?.volumes ?? []).some((v) => v.startsWith('./haproxy.cfg:')), 'compose.yaml: haproxy does not mount docker/haproxy.cfg');

// ---- k8s ----
const kustomization = parseAll('docker/k8s/kustomization.yaml')[0];
const objects = {};
for (const file of kustomization.resources) {
  check(fs.existsSync(path.join(root, 'docker/k8s', file)), `kustomization.yaml: ${file} is missing`);
  for (const o of parseAll(`docker/k8s/${file}`)) {
    check(o.apiVersion && o.kind && o.metadata?.name, `docker/k8s/${file}: an object without apiVersion, kind or name`);
    objects[`${o.kind}/${o.metadata.name}`] = o;
  }
}
const deployment = objects['Deployment/mtlod'];
check(deployment, 'k8s: no Deployment mtlod');
const pod = deployment?.spec?.template?.spec ?? {};
const container = (pod.containers ?? [])[0] ?? {};
checkFlags('deployment.yaml', container.args ?? []);
check(container.readinessProbe && container.livenessProbe, 'deployment.yaml: readiness and liveness probes are required');
for (const kind of ['requests', 'limits']) {
  check(container.resources?.[kind]?.cpu && container.resources?.[kind]?.memory, `deployment.yaml: resources.${kind} needs cpu and memory`);
}
check(pod.securityContext?.runAsNonRoot === true, 'deployment.yaml: must run as non-root');
const config = objects['ConfigMap/mtlod-limits']?.data ?? {};
const defined = new Set([...Object.keys(config), ...(container.env ?? []).map((e) => e.name)]);
for (const arg of container.args ?? []) {
  for (const m of arg.matchAll(/\$\(([A-Z0-9_]+)\)/g)) check(defined.has(m[1]), `deployment.yaml: ${arg} uses $(${m[1]}), which nothing defines`);
}
const drainSeconds = Number(config.MTLOD_DRAIN_TIMEOUT_MS) / 1000;
check(pod.terminationGracePeriodSeconds > drainSeconds,
  `deployment.yaml: terminationGracePeriodSeconds ${pod.terminationGracePeriodSeconds} must exceed the drain timeout (${drainSeconds} s)`);
const service = objects['Service/mtlod'];
const portNames = new Set((container.ports ?? []).map((p) => p.name));
for (const p of service?.spec?.ports ?? []) check(portNames.has(p.targetPort), `service.yaml: targetPort ${p.targetPort} is no container port`);
check(JSON.stringify(service?.spec?.selector) === JSON.stringify(deployment?.spec?.selector?.matchLabels),
  'service.yaml: the selector does not match the Deployment');
const hpa = objects['HorizontalPodAutoscaler/mtlod'];
check(hpa?.spec?.scaleTargetRef?.name === 'mtlod' && hpa.spec.minReplicas >= 2, 'hpa.yaml: must scale Deployment mtlod from at least 2');
const claim = pod.volumes?.find((v) => v.persistentVolumeClaim)?.persistentVolumeClaim?.claimName;
check(objects[`PersistentVolumeClaim/${claim}`], `deployment.yaml: claim ${claim} is not defined`);

// ---- Dockerfile ----
const dockerfile = read('docker/Dockerfile');
const cmd = dockerfile.match(/^CMD (\[[\s\S]*?\])\s*$/m);
check(cmd, 'Dockerfile: no CMD');
if (cmd) checkFlags('Dockerfile CMD', JSON.parse(cmd[1].replace(/\\\n/g, ' ')));
check(/^USER (?!root)\S+/m.test(dockerfile), 'Dockerfile: must switch to a non-root USER');
check(/^HEALTHCHECK /m.test(dockerfile), 'Dockerfile: no HEALTHCHECK');
check(/scripts\/bootstrap\.sh --profile build/.test(dockerfile) && /bootstrap\.sh --profile runtime/.test(dockerfile),
  'Dockerfile: dependencies must come from scripts/bootstrap.sh');

if (failures.length) {
  for (const f of failures) console.error(`FAIL ${f}`);
  process.exit(1);
}
console.log(`docker/ manifests consistent: ${replicas.length} compose replicas, ${Object.keys(objects).length} k8s objects, ${used.size} haproxy variables`);
