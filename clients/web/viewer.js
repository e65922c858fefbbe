// mtlod viewer: orbit the model, and the server sends a view-dependent cut refined near
// the silhouette and around the mouse (the gaze/focus point of the attention-driven papers). A built-in
// scene (PROTOCOL.md, "Scenes") shows many placed instances of the served models, cut together. Speaks
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
// A scene's instances: one mesh each, in the request's order, placed by the matrix the page sent
// (matrixAutoUpdate off: the matrix is the instance's, not composed from position and rotation).
const instanceGroup = new THREE.Group();
instanceGroup.visible = false;
scene.add(instanceGroup);

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
  models: [],            // the server's models, as list_models names them
  scene: null,           // the scene shown: {name, instances: [{model, matrix}], lo, hi (its world box)}; null: one model
  maxInFlight: 1,        // requests the server takes unanswered from this connection (hello's limits)
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

// The built-in scenes, each a name for the panel's select and ?scene= in the URL, and a function of the
// server's models (model_info replies with their `name`; at most SCENE_MODELS of them, in list_models'
// order) giving the instances, [{model, matrix}], matrices model → world, column-major and affine.
const SCENES = {
  room: { label: 'room (16 instances)', build: roomInstances },
};
const SCENE_MODELS = 4;

// A matrix, column-major as the protocol and three.js store it, that stands a model on the floor: its
// box's bottom centre to the origin, scaled so the box's largest side is `size`, turned by `angle`
// radians about y (up), then moved to `at` ([x, z] on the floor).
function placement(info, size, angle, at) {
  const lo = info.bounds_min, hi = info.bounds_max;
  const scale = size / Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
  const matrix = new THREE.Matrix4().makeTranslation(at[0], 0, at[1])
    .multiply(new THREE.Matrix4().makeRotationY(angle))
    .multiply(new THREE.Matrix4().makeScale(scale, scale, scale))
    .multiply(new THREE.Matrix4().makeTranslation(-(lo[0] + hi[0]) / 2, -lo[1], -(lo[2] + hi[2]) / 2));
  return Array.from(matrix.elements);
}

// A room: 4 rows of 4 on the floor, the models taking turns along rows and columns (so each model
// repeats), every instance scaled to a common size (largest side 1) whatever its model's units and
// turned by the golden angle from the one before, odd rows shifted by a quarter step. From the default
// camera, raised in front, the rows behind show between and above the rows in front, partly hidden.
function roomInstances(models) {
  const rows = 4, columns = 4, step = 1.3;
  const goldenAngle = Math.PI * (3 - Math.sqrt(5));
  const instances = [];
  for (let r = 0; r < rows; ++r) {
    for (let c = 0; c < columns; ++c) {
      const info = models[(r + c) % models.length];
      const at = [(c - (columns - 1) / 2 + (r % 2 ? 0.25 : -0.25)) * step, (r - (rows - 1) / 2) * step];
      instances.push({ model: info.name, matrix: placement(info, 1, instances.length * goldenAngle, at) });
    }
  }
  return instances;
}

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
  // The scene: none (the model select's model) or a built-in one; ?scene= in the page's URL picks it.
  const named = new URLSearchParams(location.search).get('scene');
  const none = !Object.hasOwn(SCENES, named);
  $('scene').append(new Option('none: one model', '', none, none));
  for (const [name, s] of Object.entries(SCENES)) $('scene').append(new Option(s.label, name, name === named, name === named));
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
let sentScene = null;        // the scene of the last extract sent (null: a model), which its gazes' replies show too

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
  // A scene names its instances instead of a model; it cannot carry labels, and each instance's
  // colours come as its model has them (asking for colours would be refused for a model without).
  const request = {
    type: 'extract', ...(state.scene ? { scene: { instances: state.scene.instances } } : { model: state.model }),
    camera: { view: Array.from(camera.matrixWorldInverse.elements), projection: Array.from(camera.projectionMatrix.elements),
              viewport: [width, height] },
    grid: [Math.min(512, Math.round(width / 2)), Math.min(512, Math.round(height / 2))],
    error: { value: Number($('error').value), unit: 'pixels' },
    criteria,
    attributes: state.scene ? { normals: true } : { normals: true, labels: wantLabels(), colors: state.colors },
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
  if (inFlight || !state.connected || !(state.model || state.scene)) return;
  let sending;
  // Requests per instance cannot be gazed at: a pointer move asks for every instance again.
  if (wantExtract || (wantGaze && perInstance())) {
    sentScene = state.scene;
    sending = perInstance() ? sendPerInstance() : send(extractRequest());
    wantExtract = false;
    wantGaze = null;
  } else if (wantGaze) {
    sending = send({ type: 'gaze', x: wantGaze[0], y: wantGaze[1] });
    wantGaze = null;
  } else {
    return;
  }
  inFlight = true;
  sending.then(showReply).finally(() => {
    inFlight = false;
    pump();
  });
}

// A scene as a client without scene requests fetches it, to compare with one scene request on the
// same page: one extract per instance, its camera's view taking the instance's matrix in (the server
// holds the pixel bound on the screen whatever the matrix scales), the budget split evenly, and whole
// meshes (a connection keeps one delta state per model, and models repeat). Each request sees its
// instance alone: no silhouettes where instances meet, nothing hidden by another.
function perInstance() {
  return state.scene !== null && $('scene-requests').value === 'instances';
}

// The replies joined as one scene reply (the instances' payloads one after the other), which
// showReply draws as it draws the server's; the first error, if any, instead.
async function sendPerInstance() {
  const request = extractRequest();
  delete request.scene;
  delete request.delta;
  const view = new THREE.Matrix4().fromArray(request.camera.view);
  const instances = sentScene.instances;
  const requestFor = (instance) => {
    const own = structuredClone(request);
    own.model = instance.model;
    own.camera.view = Array.from(view.clone().multiply(new THREE.Matrix4().fromArray(instance.matrix)).elements);
    if (request.budget) own.budget = Math.max(1, Math.floor(request.budget / instances.length));
    return own;
  };
  // No more unanswered at once than the server takes from a connection (hello's limits).
  const replies = new Array(instances.length);
  let next = 0;
  const lanes = Math.min(instances.length, Math.max(1, state.maxInFlight));
  await Promise.all(Array.from({ length: lanes }, async () => {
    while (next < instances.length) {
      const i = next++;
      replies[i] = await send(requestFor(instances[i]));
    }
  }));
  const failed = replies.find(({ json }) => json.type !== 'mesh');
  if (failed) return failed;
  const sum = (key) => replies.reduce((total, { json }) => total + json[key], 0);
  const payload = new Uint8Array(sum('bytes'));
  let at = 0;
  for (const { payload: part } of replies) {
    payload.set(new Uint8Array(part), at);
    at += part.byteLength;
  }
  const json = { type: 'mesh', codec: replies[0].json.codec, triangles: sum('triangles'), vertices: sum('vertices'),
                 bytes: payload.byteLength, requests: replies.length,
                 timings_us: { total: Math.max(...replies.map(({ json: j }) => j.timings_us.total)) },
                 instances: replies.map(({ json: j }) => ({ model: j.model, triangles: j.triangles, bytes: j.bytes })) };
  return { json, payload: payload.buffer, latencyMs: Math.max(...replies.map((r) => r.latencyMs)) };
}

// Labels come in Draco payloads only: the checkbox is off limits for other codecs.
function wantLabels() {
  return $('labels').checked && CODECS[$('codec').value].labels && !state.scene;
}

function showCodec() {
  $('labels').disabled = !CODECS[$('codec').value].labels || state.scene !== null;
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

// A mesh kept across delta replies (PROTOCOL.md, "Delta replies"): 9 floats per triangle (and 9 for its
// corners' normals and 9 for their colours), keyed by the triangle's id in the model's Multi-Tessellation;
// removal swaps in the last triangle. The single model has one, and every scene instance its own: a
// scene reply's deltas are per instance, each against that instance's previous mesh.
const keptArrays = ['positions', 'normals', 'colors'];
function newKept() {
  const kept = { ids: [], slot: new Map(), hasNormals: false, hasColors: false };
  for (const key of keptArrays) kept[key] = new Float32Array(9 * 1024);
  return kept;
}
const modelKept = newKept();
const instanceKept = [];     // by instance: kept as long as the page runs, as the server keeps its side

function keptRemove(kept, id) {
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

function keptAdd(kept, id, corners, normals, colours) {
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

// Applies a delta to a kept mesh and returns a geometry showing it. The mesh part of the payload keeps the
// cut's triangle order in every codec: its face f is the f-th added id.
async function applyDelta(kept, codec, delta, payload) {
  if (delta.reset) {
    kept.ids.length = 0;
    kept.slot.clear();
  }
  // A reply without payload (nothing changed) comes as a text message: payload is null. The mesh part's
  // length was named `draco_bytes` before meshopt payloads came; servers send both names for now.
  const meshBytes = delta.payload_bytes ?? delta.draco_bytes;
  const ids = new DataView(payload ?? new ArrayBuffer(0), meshBytes);
  for (let i = 0; i < delta.removed; ++i) keptRemove(kept, ids.getUint32(4 * (delta.added + i), true));
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
      keptAdd(kept, ids.getUint32(4 * f, true), corners, normals, colours);
    }
    kept.hasNormals = normal !== undefined;
    kept.hasColors = color !== undefined;
    added.dispose();
  }
  const geometry = new THREE.BufferGeometry();
  const floats = 9 * kept.ids.length;
  geometry.setAttribute('position', new THREE.BufferAttribute(kept.positions.slice(0, floats), 3));
  if (kept.hasNormals) geometry.setAttribute('normal', new THREE.BufferAttribute(kept.normals.slice(0, floats), 3));
  if (kept.hasColors) geometry.setAttribute('color', new THREE.BufferAttribute(kept.colors.slice(0, floats), 3));
  return geometry;
}

// One mesh's part of a reply (the single model's, or one instance's) as a geometry: a whole mesh decoded,
// or the kept mesh after the part's delta, which must then hold the server's `triangles`.
async function partGeometry(codec, { kept, delta, payload, triangles }) {
  if (!delta) return decodePayload(codec, payload);
  const geometry = await applyDelta(kept, codec, delta, payload);
  if (kept.ids.length !== triangles) {
    geometry.dispose();
    throw new Error(`the kept mesh has ${kept.ids.length} triangles, the server's cut ${triangles}`);
  }
  return geometry;
}

// A scene reply's parts: the payload cut by the instances' `bytes`, in order (PROTOCOL.md, "Scenes").
function sceneParts(json, payload) {
  const total = payload ? payload.byteLength : 0;
  const sum = json.instances.reduce((bytes, instance) => bytes + instance.bytes, 0);
  if (sum !== total) throw new Error(`the scene's payload has ${total} bytes, its instances ${sum}`);
  while (instanceKept.length < json.instances.length) instanceKept.push(newKept());
  let at = 0;
  return json.instances.map((instance, i) => {
    at += instance.bytes;
    return { kept: instanceKept[i], delta: instance.delta, payload: payload ? payload.slice(at - instance.bytes, at) : null,
             triangles: instance.triangles };
  });
}

// Decodes every part (in parallel: each has its own kept mesh), or none: on the first failure the
// geometries decoded are dropped and the error thrown.
async function partGeometries(codec, parts) {
  const settled = await Promise.allSettled(parts.map((part) => partGeometry(codec, part)));
  const failed = settled.find((s) => s.status === 'rejected');
  if (!failed) return settled.map((s) => s.value);
  for (const s of settled) if (s.status === 'fulfilled') s.value.dispose();
  throw failed.reason;
}

// The meshes of a scene's `count` instances, made or dropped to match.
function instanceMeshes(count) {
  while (instanceGroup.children.length > count) {
    const gone = instanceGroup.children.at(-1);
    gone.geometry.dispose();
    instanceGroup.remove(gone);
  }
  while (instanceGroup.children.length < count) {
    const made = new THREE.Mesh(new THREE.BufferGeometry(), material);
    made.matrixAutoUpdate = false;
    instanceGroup.add(made);
  }
  return instanceGroup.children;
}

const triangleCount = (geometry) => (geometry.index ? geometry.index.count : geometry.getAttribute('position').count) / 3;

async function showReply({ json, payload, latencyMs }) {
  if (json.type === 'error') {
    if (json.code !== 'superseded') setStatus(`${json.code}: ${json.message}`, true);
    return;
  }
  if (json.type !== 'mesh') return;
  // Replies from servers that predate the `codec` field carry Draco.
  const codec = json.codec ?? 'draco';
  // A scene reply shows the scene of the last extract sent (a gaze's reply too: the server re-extracts
  // its connection's latest extract).
  const placed = Array.isArray(json.instances);
  const delta = placed ? json.instances.some((instance) => instance.delta) : json.delta !== undefined;
  let geometries;
  try {
    if (placed && (!sentScene || sentScene.instances.length !== json.instances.length)) {
      throw new Error(`a scene reply of ${json.instances.length} instances, the page sent ${sentScene?.instances.length ?? 'none'}`);
    }
    const parts = placed ? sceneParts(json, payload)
                         : [{ kept: modelKept, delta: json.delta, payload, triangles: json.triangles }];
    geometries = await partGeometries(codec, parts);
  } catch (error) {
    // After a delta that did not apply the next view asks for whole meshes, which put the kept ones right;
    // a damaged whole mesh leaves the meshes shown as they were.
    if (delta) {
      wholeNext = true;
      requestExtract();
    }
    return setStatus(String(error.message ?? error), true);
  }
  if (!delta) wholeNext = false;
  const meshes = placed ? instanceMeshes(geometries.length) : [mesh];
  mesh.visible = !placed;
  instanceGroup.visible = placed;
  // Label colours (colourByLabel) replace the model's own while labels are shown; scenes carry no labels.
  const labelled = !placed && $('labels').checked && colourByLabel(geometries[0]);
  meshes.forEach((shown, i) => {
    shown.geometry.dispose();
    shown.geometry = geometries[i];
    shown.material = labelled || geometries[i].getAttribute('color') !== undefined ? vertexColourMaterial : material;
    if (placed) shown.matrix.fromArray(sentScene.instances[i].matrix);
  });
  setLook();
  const has = (name) => geometries.every((g) => g.getAttribute(name) !== undefined);
  state.displayedTriangles = geometries.reduce((sum, g) => sum + triangleCount(g), 0);
  state.lastReply = json;
  state.lastReplyHadLabels = has('label');
  state.lastReplyHadColors = geometries.some((g) => g.getAttribute('color') !== undefined) && !labelled;
  state.lastReplyHadNormals = has('normal');
  state.deltaNormals = modelKept.hasNormals;
  state.meshes += 1;
  $('scene-totals').hidden = !placed;
  if (placed) $('instances').textContent = String(json.instances.length);
  $('triangles').textContent = String(state.displayedTriangles);
  const vertices = geometries.reduce((sum, g) => sum + g.getAttribute('position').count, 0);
  $('vertices').textContent = delta ? `${json.vertices} new` : String(vertices);
  $('bytes').textContent = String(json.bytes);
  $('latency').textContent = latencyMs.toFixed(1);
  $('server-ms').textContent = (json.timings_us.total / 1000).toFixed(1);
  if (json.focus) $('focus-point').textContent = `${json.focus[0].toFixed(3)}, ${json.focus[1].toFixed(3)}`;
  $('meshes').textContent = String(state.meshes);
  if (placed) {
    // Under a budget too small for even the coarsest meshes of every instance, those are what is shown.
    const how = json.requests ? `, ${json.requests} requests` : '';
    setStatus(`ok: scene ${sentScene.name}${how}${json.within_budget === false ? ', over the budget at its coarsest' : ''}`);
  } else {
    // The model's file changed on the server: this cut comes from its new version.
    setStatus(json.model_changed ? `ok: ${state.model} was updated (version ${json.model_version})` : 'ok');
  }
}

// Frames the box lo..hi: the camera looks at its centre from `direction`, far enough for the box's
// bounding sphere to fill the view's height, or with `tight` for the box's corners to fit the view (its
// height and its width) with 5 % to spare: a flat scene seen from above its floor fills more of the view.
function frame(lo, hi, direction, tight = false) {
  resize();
  const centre = lo.clone().add(hi).multiplyScalar(0.5);
  const radius = hi.clone().sub(lo).length() / 2;
  const back = direction.clone().normalize();
  const tanHeight = Math.tan(THREE.MathUtils.degToRad(camera.fov / 2)), tanWidth = tanHeight * camera.aspect;
  let distance = radius / tanHeight;
  if (tight) {
    const right = new THREE.Vector3(0, 1, 0).cross(back).normalize(), up = back.clone().cross(right);
    distance = 0;
    for (let k = 0; k < 8; ++k) {
      const corner = new THREE.Vector3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z).sub(centre);
      distance = Math.max(distance, corner.dot(back) + Math.max(Math.abs(corner.dot(right)) / tanWidth,
                                                                Math.abs(corner.dot(up)) / tanHeight));
    }
    distance *= 1.05;
  }
  camera.near = radius / 100;
  camera.far = radius * 100;
  camera.updateProjectionMatrix();
  camera.position.copy(centre).addScaledVector(back, distance);
  controls.target.copy(centre);
  controls.update();
  // The move's 'change' asked for a view in 50 ms; the caller asks for it now, once.
  clearTimeout(extractTimer);
  extractTimer = null;
}

async function selectModel(name) {
  const { json } = await send({ type: 'model_info', model: name });
  if (json.type !== 'model_info') return setStatus(`model_info: ${json.message}`, true);
  state.model = name;
  state.scene = null;
  $('scene-requests-row').hidden = true;
  showCodec();
  state.colors = json.colors === true;
  const lo = new THREE.Vector3(...json.bounds_min), hi = new THREE.Vector3(...json.bounds_max);
  state.bounds = { lo, hi };
  frame(lo, hi, new THREE.Vector3(0, 0, 1));
  wantExtract = true;
  pump();
}

// Opens a built-in scene (SCENES) of the server's first models: their bounds place the instances, and
// the camera frames the scene's world box from the front, raised so the rows behind show.
async function selectScene(name) {
  const infos = await Promise.all(state.models.slice(0, SCENE_MODELS).map((model) => send({ type: 'model_info', model })));
  const failed = infos.find(({ json }) => json.type !== 'model_info');
  if (failed) return setStatus(`model_info: ${failed.json.message}`, true);
  if (infos.length === 0) return setStatus('the server has no model', true);
  const models = infos.map(({ json }, i) => ({ ...json, name: state.models[i] }));
  const instances = SCENES[name].build(models);
  const box = new THREE.Box3(), placed = new THREE.Box3();
  for (const instance of instances) {
    const info = models.find((m) => m.name === instance.model);
    placed.set(new THREE.Vector3(...info.bounds_min), new THREE.Vector3(...info.bounds_max));
    box.union(placed.applyMatrix4(new THREE.Matrix4().fromArray(instance.matrix)));
  }
  state.scene = { name, instances, lo: box.min, hi: box.max };
  $('scene-requests-row').hidden = false;  // how the scene is asked for: only a scene has the choice
  showCodec();
  frame(box.min, box.max, new THREE.Vector3(0, 0.6, 1), true);
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
// `instance` picks a scene instance's kept mesh; without it, the single model's.
state.keptMesh = (instance) => {
  const kept = instance === undefined ? modelKept : instanceKept[instance];
  const floats = 9 * kept.ids.length;
  return { ids: Uint32Array.from(kept.ids), positions: kept.positions.slice(0, floats),
           normals: kept.hasNormals ? kept.normals.slice(0, floats) : null,
           colors: kept.hasColors ? kept.colors.slice(0, floats) : null };
};
// The scene's meshes as three.js draws them, for tests (tests/clients/viewer_scene_test.mjs): per instance
// its triangles, its matrixWorld (column-major, as of the last frame drawn), its attributes and its kept
// mesh's size; empty when no scene is shown. drawnMeshes() counts the visible meshes of the whole page.
state.instances = () => (instanceGroup.visible ? instanceGroup.children : []).map((shown, i) => ({
  triangles: triangleCount(shown.geometry), matrixWorld: Array.from(shown.matrixWorld.elements),
  normals: shown.geometry.getAttribute('normal') !== undefined, colors: shown.geometry.getAttribute('color') !== undefined,
  kept: instanceKept[i]?.ids.length ?? 0,
}));
state.drawnMeshes = () => {
  let count = 0;
  scene.traverseVisible((object) => { if (object.isMesh) count += 1; });
  return count;
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
for (const id of ['error', 'budget', ...criteriaControls, 'falloff', 'hidden-factor', 'labels', 'delta', 'codec',
                  'scene-requests']) {
  $(id).addEventListener('change', requestExtract);
}
$('codec').addEventListener('change', () => {
  showCodec();
  wholeNext = true;
});
// Wireframe and flat shading change only how the mesh shown is drawn. A mesh without normals
// (none sent) can only be drawn flat.
function setLook() {
  const shown = instanceGroup.visible ? instanceGroup.children : [mesh];
  const flat = $('flat').checked || shown.some((m) => m.geometry.getAttribute('normal') === undefined);
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
// A model chosen in the panel is shown alone: the scene select goes back to none.
$('model').addEventListener('change', () => {
  $('scene').value = '';
  selectModel($('model').value);
});
$('scene').addEventListener('change', () => {
  const name = $('scene').value;
  return Object.hasOwn(SCENES, name) ? selectScene(name) : selectModel($('model').value);
});

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
    const hello = await send({ type: 'hello', version: 1, client: 'mtlod-viewer/0.1' });
    state.maxInFlight = hello.json.limits?.max_in_flight ?? 1;
    const { json } = await send({ type: 'list_models' });
    state.models = json.models.map((m) => m.name);
    const select = $('model');
    for (const m of json.models) select.add(new Option(`${m.name} (${m.input_triangles} triangles)`, m.name));
    const wanted = new URLSearchParams(location.search).get('model');
    const first = json.models.find((m) => m.name === wanted) ?? json.models[0];
    if (!first) return setStatus('the server has no model', true);
    select.value = first.name;
    setStatus('loading');
    if (Object.hasOwn(SCENES, $('scene').value)) {
      state.model = first.name;
      await selectScene($('scene').value);
    } else {
      await selectModel(first.name);
    }
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
