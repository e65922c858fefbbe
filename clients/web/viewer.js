// mtlod viewer: orbit the model, and the server sends a view-dependent cut refined near
// the silhouette and around the mouse (the gaze/focus point of the attention-driven papers). Speaks
// protocol/PROTOCOL.md over the /ws WebSocket: text messages are JSON, binary messages are whole
// frames (8-byte header, JSON, the mesh payload: Draco or meshoptimizer, as the panel's codec asks).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { CODECS, decodePayload } from './codecs.js';

const $ = (id) => document.getElementById(id);
const container = $('view');

const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
container.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x202428);
scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 2.0));
const sun = new THREE.DirectionalLight(0xffffff, 1.5);
scene.add(sun);
const camera = new THREE.PerspectiveCamera(45, 1, 0.01, 100);
const controls = new OrbitControls(camera, renderer.domElement);

// Smooth shading with the normals the server sends (the original surface's, at every vertex of
// every cut); flat shading, a toggle, shows the cut's facets. Both sides of every triangle are drawn:
// scans wound inwards (bunny-zipper) or with clashing orientation (the dragon_vrip_res* files) would
// otherwise show their far side or holes (tests/evaluation/VIEWER.md); back faces are lit with the
// normal turned towards the eye.
// The materials start flat, as the empty geometry before the first mesh is drawn: three.js compiles a
// material drawn on a geometry without normals as flat-shaded whatever its flatShading says, and does not
// look again when a later geometry brings normals, so setLook keeps flatShading equal to what a program
// compiled for the mesh shown does and recompiles when that changes.
const material = new THREE.MeshStandardMaterial({ color: 0xc8c0b0, roughness: 0.8, side: THREE.DoubleSide, flatShading: true });
const vertexColourMaterial = new THREE.MeshStandardMaterial({ vertexColors: true, roughness: 0.8, side: THREE.DoubleSide,
                                                              flatShading: true });
const mesh = new THREE.Mesh(new THREE.BufferGeometry(), material);
scene.add(mesh);

// State the page shares with tests (tests/clients/viewer_test.mjs).
const state = {
  connected: false,
  model: null,
  bounds: null,
  meshes: 0,            // mesh replies decoded and shown
  lastReply: null,      // JSON of the last mesh reply
  lastReplyHadLabels: false,  // its payload carried the `label` attribute (Draco only)
  lastReplyHadColors: false,  // the mesh shown has the model's vertex colours
  lastReplyHadNormals: false, // the mesh shown has the server's vertex normals
  flatShading: false,   // the mesh is drawn with its facets' normals
  colors: false,        // the model has vertex colours: they are asked for and shown
  deltaNormals: false,  // the kept delta mesh has normals
  displayedTriangles: 0,
  focus: [0.5, 0.5],     // the gaze criterion's point: follows the mouse
  neglect: [0.5, 0.5],   // the neglect region's point: where the last shift-click was
  errors: [],
};
window.mtlod = state;

// The criteria of the protocol (protocol/PROTOCOL.md, "Criteria"), each a checkbox `name` with its
// `name-distance` and `name-factor`: the panel is built from this list and extractRequest sends
// every checked one. `point` names the state entry holding a point-seeded criterion's point.
const CRITERIA = [
  { name: 'silhouette', label: 'silhouette', distance: 2, factor: 0, min: 0, max: 1 },
  { name: 'focus', label: 'focus follows the mouse', distance: 80, factor: 1, min: 0, max: 1, on: true, point: 'focus' },
  { name: 'neglect', label: 'neglect (shift-click places it)', distance: 50, factor: 4, min: 1, max: 1e6, point: 'neglect' },
  { name: 'screen_edge', label: 'screen edge coarser', distance: 32, factor: 2, min: 1, max: 1e6 },
];
// The falloff laws (protocol/messages.hpp, kFalloffNames); the default is the study's winner.
const FALLOFFS = ['step', 'linear', 'smoothstep', 'foveal'];
const DEFAULT_FALLOFF = 'foveal';

function buildCriteriaPanel() {
  const panel = $('criteria');
  const input = (id, attributes) => Object.assign(document.createElement('input'), { id, ...attributes });
  const row = (text, element) => {
    const label = document.createElement('label');
    label.append(text, element);
    panel.append(label);
  };
  for (const c of CRITERIA) {
    const label = document.createElement('label');
    const span = document.createElement('span');
    span.append(input(c.name, { type: 'checkbox', checked: Boolean(c.on) }), ` ${c.label}`);
    label.append(span);
    panel.append(label);
    row('\u00a0 threshold (px) ', input(`${c.name}-distance`, { type: 'number', value: c.distance, min: 0, step: 1 }));
    row('\u00a0 factor ', input(`${c.name}-factor`, { type: 'number', value: c.factor, min: c.min, max: c.max, step: 0.05 }));
  }
  for (const law of FALLOFFS) $('falloff').append(new Option(law, law, law === DEFAULT_FALLOFF, law === DEFAULT_FALLOFF));
  // The payload's codec (codecs.js): the first is the default, ?codec= in the page's URL picks another.
  const wanted = new URLSearchParams(location.search).get('codec');
  const first = Object.hasOwn(CODECS, wanted) ? wanted : Object.keys(CODECS)[0];
  for (const [name, codec] of Object.entries(CODECS)) $('codec').append(new Option(codec.label, name, name === first, name === first));
  showCodec();
}
buildCriteriaPanel();

let ws = null;
let nextId = 1;
const waiting = new Map();   // id → {resolve, sentAt}
let inFlight = false;        // one extraction at a time from this page: the next waits for the reply
let wantExtract = false;
let wantGaze = null;
let wholeNext = false;       // the next extract asks for a whole mesh (see extractRequest)

function setStatus(text, error = false) {
  $('status').textContent = text;
  $('status').classList.toggle('error', error);
  if (error) state.errors.push(text);
}

function send(message) {
  const id = nextId++;
  message.id = id;
  ws.send(JSON.stringify(message));
  return new Promise((resolve) => waiting.set(id, { resolve, sentAt: performance.now() }));
}

// A reply: text is JSON only; binary is a frame whose payload follows the JSON.
function onMessage(event) {
  let json, payload = null;
  if (typeof event.data === 'string') {
    json = JSON.parse(event.data);
  } else {
    const view = new DataView(event.data);
    const jsonBytes = view.getUint32(0, true), payloadBytes = view.getUint32(4, true);
    json = JSON.parse(new TextDecoder().decode(new Uint8Array(event.data, 8, jsonBytes)));
    payload = event.data.slice(8 + jsonBytes, 8 + jsonBytes + payloadBytes);
  }
  const pending = waiting.get(json.id);
  if (pending) {
    waiting.delete(json.id);
    pending.resolve({ json, payload, latencyMs: performance.now() - pending.sentAt });
  } else if (json.type === 'error') {
    setStatus(`${json.code}: ${json.message}`, true);
  }
}

function viewportSize() {
  return [Math.max(1, container.clientWidth), Math.max(1, container.clientHeight)];
}

function extractRequest() {
  const [width, height] = viewportSize();
  camera.updateMatrixWorld();
  // The default (foveal falloff, focus factor 1, no silhouette band, hidden surfaces ×16) is the winner
  // of the image-space studies, tests/evaluation/FIDELITY.md and, on this page's own pixels, VIEWER.md:
  // the bound holds at the focus and grows with eccentricity, and what the camera cannot see gets few
  // triangles. The bound (index.html) is 0.25 px: at the clients' 1 px the facets show at 1280×720.
  const criteria = { falloff: $('falloff').value, hidden_factor: Math.max(1, Number($('hidden-factor').value) || 1) };
  for (const c of CRITERIA) {
    if (!$(c.name).checked) continue;
    const law = { distance: Number($(`${c.name}-distance`).value), factor: Number($(`${c.name}-factor`).value) };
    criteria[c.name] = c.point ? [{ x: state[c.point][0], y: state[c.point][1], ...law }] : law;
  }
  const request = {
    type: 'extract', model: state.model,
    camera: { view: Array.from(camera.matrixWorldInverse.elements), projection: Array.from(camera.projectionMatrix.elements),
              viewport: [width, height] },
    grid: [Math.min(512, Math.round(width / 2)), Math.min(512, Math.round(height / 2))],
    error: { value: Number($('error').value), unit: 'pixels' },
    criteria,
    attributes: { normals: true, labels: wantLabels(), colors: state.colors },
    codec: $('codec').value,
  };
  // Delta replies send only what changed, named by triangle id; labels would go stale on kept triangles.
  // After a delta that did not apply, or a change of codec (whose grid may round a vertex differently
  // from the other's), one whole mesh puts the kept mesh right again.
  if ($('delta').checked && !wantLabels() && !wholeNext) request.delta = true;
  const budget = Number($('budget').value);
  if (budget > 0) request.budget = budget;
  return request;
}

// Sends what the user asked for last: a new view wins over a gaze (it carries the focus too).
function pump() {
  if (inFlight || !state.connected || !state.model) return;
  let request;
  if (wantExtract) {
    request = extractRequest();
    wantExtract = false;
    wantGaze = null;
  } else if (wantGaze) {
    request = { type: 'gaze', x: wantGaze[0], y: wantGaze[1] };
    wantGaze = null;
  } else {
    return;
  }
  inFlight = true;
  send(request).then(showReply).finally(() => {
    inFlight = false;
    pump();
  });
}

// Labels come in Draco payloads only: the checkbox is off limits for other codecs.
function wantLabels() {
  return $('labels').checked && CODECS[$('codec').value].labels;
}

function showCodec() {
  $('labels').disabled = !CODECS[$('codec').value].labels;
}

function colourByLabel(geometry) {
  const labels = geometry.getAttribute('label');
  if (!labels) return false;
  let top = 1;
  for (let i = 0; i < labels.count; ++i) top = Math.max(top, labels.getX(i));
  const colours = new Float32Array(labels.count * 3);
  const c = new THREE.Color();
  for (let i = 0; i < labels.count; ++i) {
    // Near the silhouette or focus (small labels) red, far away blue, as in the papers' figure 2.
    c.setHSL(0.66 * Math.sqrt(labels.getX(i) / top), 0.9, 0.5);
    colours.set([c.r, c.g, c.b], 3 * i);
  }
  geometry.setAttribute('color', new THREE.BufferAttribute(colours, 3));
  return true;
}

// The mesh kept across delta replies (PROTOCOL.md, "Delta replies"): 9 floats per triangle (and 9
// for its corners' normals and 9 for their colours), keyed by the triangle's id in the model's
// Multi-Tessellation; removal swaps in the last triangle.
const keptArrays = ['positions', 'normals', 'colors'];
const kept = { ids: [], slot: new Map() };
for (const key of keptArrays) kept[key] = new Float32Array(9 * 1024);

function keptRemove(id) {
  const slot = kept.slot.get(id);
  if (slot === undefined) throw new Error(`the delta removes triangle ${id}, which the mesh does not hold`);
  const last = kept.ids.length - 1;
  kept.slot.delete(id);
  if (slot !== last) {
    kept.ids[slot] = kept.ids[last];
    for (const key of keptArrays) kept[key].copyWithin(9 * slot, 9 * last, 9 * last + 9);
    kept.slot.set(kept.ids[slot], slot);
  }
  kept.ids.pop();
}

function keptAdd(id, corners, normals, colours) {
  if (kept.slot.has(id)) throw new Error(`the delta adds triangle ${id}, which the mesh already holds`);
  const slot = kept.ids.length;
  if (9 * (slot + 1) > kept.positions.length) {
    for (const key of keptArrays) {
      const grown = new Float32Array(2 * kept[key].length);
      grown.set(kept[key]);
      kept[key] = grown;
    }
  }
  kept.positions.set(corners, 9 * slot);
  if (normals) kept.normals.set(normals, 9 * slot);
  if (colours) kept.colors.set(colours, 9 * slot);
  kept.ids.push(id);
  kept.slot.set(id, slot);
}

// Applies a delta reply to the kept mesh and returns a geometry showing it. The mesh part of the payload
// keeps the cut's triangle order in every codec: its face f is the f-th added id.
async function applyDelta(codec, delta, payload) {
  if (delta.reset) {
    kept.ids.length = 0;
    kept.slot.clear();
  }
  // A reply without payload (nothing changed) comes as a text message: payload is null. The mesh part's
  // length was named `draco_bytes` before meshopt payloads came; servers send both names for now.
  const meshBytes = delta.payload_bytes ?? delta.draco_bytes;
  const ids = new DataView(payload ?? new ArrayBuffer(0), meshBytes);
  for (let i = 0; i < delta.removed; ++i) keptRemove(ids.getUint32(4 * (delta.added + i), true));
  if (delta.added > 0) {
    // The ids are read after decoding: the decoder gets a copy of its part, which it may take away.
    const added = await decodePayload(codec, payload.slice(0, meshBytes));
    if (added.index.count !== 3 * delta.added) {
      added.dispose();
      throw new Error(`the delta adds ${delta.added} triangles, its ${codec} payload holds ${added.index.count / 3}`);
    }
    const index = added.index.array, position = added.getAttribute('position');
    const normal = added.getAttribute('normal'), color = added.getAttribute('color');
    const corners = new Float32Array(9), normals = normal ? new Float32Array(9) : null;
    const colours = color ? new Float32Array(9) : null;
    for (let f = 0; f < delta.added; ++f) {
      for (let k = 0; k < 3; ++k) {
        const v = index[3 * f + k];
        corners.set([position.getX(v), position.getY(v), position.getZ(v)], 3 * k);
        if (normal) normals.set([normal.getX(v), normal.getY(v), normal.getZ(v)], 3 * k);
        if (color) colours.set([color.getX(v), color.getY(v), color.getZ(v)], 3 * k);
      }
      keptAdd(ids.getUint32(4 * f, true), corners, normals, colours);
    }
    state.deltaNormals = normal !== undefined;
    added.dispose();
  }
  const geometry = new THREE.BufferGeometry();
  geometry.setAttribute('position', new THREE.BufferAttribute(kept.positions.slice(0, 9 * kept.ids.length), 3));
  if (state.deltaNormals) geometry.setAttribute('normal', new THREE.BufferAttribute(kept.normals.slice(0, 9 * kept.ids.length), 3));
  if (state.colors) geometry.setAttribute('color', new THREE.BufferAttribute(kept.colors.slice(0, 9 * kept.ids.length), 3));
  return geometry;
}

async function showReply({ json, payload, latencyMs }) {
  if (json.type === 'error') {
    if (json.code !== 'superseded') setStatus(`${json.code}: ${json.message}`, true);
    return;
  }
  if (json.type !== 'mesh') return;
  // Replies from servers that predate the `codec` field carry Draco.
  const codec = json.codec ?? 'draco';
  let geometry;
  if (json.delta) {
    try {
      geometry = await applyDelta(codec, json.delta, payload);
      if (kept.ids.length !== json.triangles) {
        throw new Error(`the kept mesh has ${kept.ids.length} triangles, the server's cut ${json.triangles}`);
      }
    } catch (error) {
      wholeNext = true;
      requestExtract();
      return setStatus(String(error.message ?? error), true);
    }
  } else {
    // A damaged payload leaves the mesh shown as it was; the next view asks for a whole mesh again.
    try {
      geometry = await decodePayload(codec, payload);
    } catch (error) {
      return setStatus(String(error.message ?? error), true);
    }
    wholeNext = false;
  }
  const labelled = $('labels').checked && colourByLabel(geometry);
  mesh.geometry.dispose();
  mesh.geometry = geometry;
  // Label colours (colourByLabel) replace the model's own while labels are shown.
  const coloured = labelled || geometry.getAttribute('color') !== undefined;
  mesh.material = coloured ? vertexColourMaterial : material;
  setLook();
  state.displayedTriangles = geometry.index ? geometry.index.count / 3 : geometry.getAttribute('position').count / 3;
  state.lastReply = json;
  state.lastReplyHadLabels = geometry.getAttribute('label') !== undefined;
  state.lastReplyHadColors = geometry.getAttribute('color') !== undefined && !labelled;
  state.lastReplyHadNormals = geometry.getAttribute('normal') !== undefined;
  state.meshes += 1;
  $('triangles').textContent = String(state.displayedTriangles);
  $('vertices').textContent = json.delta ? `${json.vertices} new` : String(geometry.getAttribute('position').count);
  $('bytes').textContent = String(json.bytes);
  $('latency').textContent = latencyMs.toFixed(1);
  $('server-ms').textContent = (json.timings_us.total / 1000).toFixed(1);
  if (json.focus) $('focus-point').textContent = `${json.focus[0].toFixed(3)}, ${json.focus[1].toFixed(3)}`;
  $('meshes').textContent = String(state.meshes);
  // The model's file changed on the server: this cut comes from its new version.
  setStatus(json.model_changed ? `ok: ${state.model} was updated (version ${json.model_version})` : 'ok');
}

async function selectModel(name) {
  const { json } = await send({ type: 'model_info', model: name });
  if (json.type !== 'model_info') return setStatus(`model_info: ${json.message}`, true);
  state.model = name;
  state.colors = json.colors === true;
  const lo = new THREE.Vector3(...json.bounds_min), hi = new THREE.Vector3(...json.bounds_max);
  const centre = lo.clone().add(hi).multiplyScalar(0.5);
  const radius = hi.clone().sub(lo).length() / 2;
  state.bounds = { lo, hi };
  camera.near = radius / 100;
  camera.far = radius * 100;
  camera.position.copy(centre).add(new THREE.Vector3(0, 0, radius / Math.tan(THREE.MathUtils.degToRad(camera.fov / 2))));
  controls.target.copy(centre);
  controls.update();
  resize();
  wantExtract = true;
  pump();
}

function resize() {
  const [width, height] = viewportSize();
  renderer.setSize(width, height);
  camera.aspect = width / height;
  camera.updateProjectionMatrix();
}

// Camera changes ask for a new view at most every 50 ms; pump() keeps one request in flight.
let extractTimer = null;
function requestExtract() {
  if (extractTimer) return;
  extractTimer = setTimeout(() => {
    extractTimer = null;
    wantExtract = true;
    pump();
  }, 50);
}

controls.addEventListener('change', requestExtract);

// Hooks for scripts that drive the page as a user would (tests/evaluation/viewer_study.mjs): place
// the camera exactly (eye and target as [x, y, z], vertical field of view in degrees; up stays +y,
// the orbit's axis), which asks for a new view as an orbit does, and tell when every change asked
// for has been answered and shown. Criteria are set through the panel's own controls.
state.setView = ({ eye, target, fov }) => {
  camera.fov = fov;
  camera.updateProjectionMatrix();
  camera.position.set(...eye);
  controls.target.set(...target);
  controls.update();
  requestExtract();
};
state.idle = () => !inFlight && !extractTimer && !wantExtract && !wantGaze;
// The mesh kept from delta replies as the page holds it, for tests that compare codecs triangle by
// triangle: ids, and per triangle 9 floats of corners (normals, colours when the mesh has them).
state.keptMesh = () => {
  const floats = 9 * kept.ids.length;
  return { ids: Uint32Array.from(kept.ids), positions: kept.positions.slice(0, floats),
           normals: state.deltaNormals ? kept.normals.slice(0, floats) : null,
           colors: state.colors ? kept.colors.slice(0, floats) : null };
};
window.addEventListener('resize', () => {
  resize();
  requestExtract();
});
renderer.domElement.addEventListener('pointermove', (event) => {
  if (!$('focus').checked || event.buttons) return;
  const rect = renderer.domElement.getBoundingClientRect();
  const x = Math.min(1, Math.max(0, (event.clientX - rect.left) / rect.width));
  const y = Math.min(1, Math.max(0, (event.clientY - rect.top) / rect.height));
  state.focus = [x, y];
  wantGaze = [x, y];
  pump();
});
renderer.domElement.addEventListener('pointerdown', (event) => {
  if (!event.shiftKey) return;
  const rect = renderer.domElement.getBoundingClientRect();
  state.neglect = [Math.min(1, Math.max(0, (event.clientX - rect.left) / rect.width)),
                   Math.min(1, Math.max(0, (event.clientY - rect.top) / rect.height))];
  if ($('neglect').checked) requestExtract();
});
const criteriaControls = CRITERIA.flatMap((c) => [c.name, `${c.name}-distance`, `${c.name}-factor`]);
for (const id of ['error', 'budget', ...criteriaControls, 'falloff', 'hidden-factor', 'labels', 'delta', 'codec']) {
  $(id).addEventListener('change', requestExtract);
}
$('codec').addEventListener('change', () => {
  showCodec();
  wholeNext = true;
});
// Wireframe and flat shading change only how the mesh shown is drawn. A mesh without normals
// (none sent) can only be drawn flat.
function setLook() {
  const flat = $('flat').checked || mesh.geometry.getAttribute('normal') === undefined;
  state.flatShading = flat;
  for (const m of [material, vertexColourMaterial]) {
    m.wireframe = $('wireframe').checked;
    if (m.flatShading !== flat) {
      m.flatShading = flat;
      m.needsUpdate = true;
    }
  }
}
for (const id of ['wireframe', 'flat']) $(id).addEventListener('change', setLook);
$('model').addEventListener('change', () => selectModel($('model').value));

function connect() {
  // ?model= goes on to the WebSocket too: a load balancer in front of replicas can route by it
  // (docker/haproxy.cfg), so each replica keeps its models hot. ?token= is the access token
  // (mtlod-server --auth-tokens), checked in the upgrade: browsers cannot set headers on a WebSocket.
  const page = new URLSearchParams(location.search);
  const query = ['model', 'token'].filter((name) => page.get(name))
    .map((name) => `${name}=${encodeURIComponent(page.get(name))}`).join('&');
  ws = new WebSocket(`${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws${query ? `?${query}` : ''}`);
  ws.binaryType = 'arraybuffer';
  ws.onmessage = onMessage;
  let opened = false;
  ws.onclose = () => {
    state.connected = false;
    // A refused upgrade (HTTP 401 for a missing or wrong token) shows only as a close before the open.
    setStatus(opened ? 'disconnected' : 'no connection: the server is down or wants a valid ?token= in the URL', true);
  };
  ws.onopen = async () => {
    opened = true;
    state.connected = true;
    await send({ type: 'hello', version: 1, client: 'mtlod-viewer/0.1' });
    const { json } = await send({ type: 'list_models' });
    const select = $('model');
    for (const m of json.models) select.add(new Option(`${m.name} (${m.input_triangles} triangles)`, m.name));
    const wanted = new URLSearchParams(location.search).get('model');
    const first = json.models.find((m) => m.name === wanted) ?? json.models[0];
    if (!first) return setStatus('the server has no model', true);
    select.value = first.name;
    setStatus('loading');
    await selectModel(first.name);
  };
}

function animate() {
  sun.position.copy(camera.position);
  renderer.render(scene, camera);
  requestAnimationFrame(animate);
}

resize();
connect();
animate();
