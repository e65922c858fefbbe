// The mesh payloads' codecs (protocol/PROTOCOL.md, the extract's `codec`), each decoded into an indexed
// three.js BufferGeometry: `position`, and when the payload carries them `normal` (unit vectors),
// `color` (linear RGB, as DRACOLoader gives it) and `label` (Draco only). Faces keep the payload's order,
// which deltas rely on (their triangle ids follow it). The viewer (viewer.js) and the decode benchmark
// (tests/bench/decode_three.mjs) use these; a codec is one entry in CODECS.
import { BufferAttribute, BufferGeometry, Color, SRGBColorSpace } from 'three';
import { DRACOLoader } from 'three/addons/loaders/DRACOLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';

// Draco through three.js's DRACOLoader, whose decoder runs in a worker. The generic uint16 attribute the
// server names `label` is Draco's GENERIC attribute: mapped by semantic name like position and normal.
const dracoLoader = new DRACOLoader();
dracoLoader.setDecoderPath('/three/examples/jsm/libs/draco/');
dracoLoader.defaultAttributeIDs.label = 'GENERIC';
dracoLoader.defaultAttributeTypes.label = 'Uint16Array';

function decodeDraco(bytes) {
  return new Promise((resolve, reject) => dracoLoader.parse(bytes, resolve, reject));
}

// The MOPT container of core/codec/meshopt_encode.hpp (its header comment is the reference): a 32-byte
// header, then u32-length-prefixed meshoptimizer streams. Lengths and counts are checked before anything
// is decoded, and the decoded values against what the header allows, as core/codec/meshopt_decode.cpp
// does: a damaged payload is an Error, never a wrong mesh or an endless allocation.
const MOPT = {
  magic: 'MOPT', version: 1, headerBytes: 32,
  hasNormals: 1, hasColors: 2, wideNormals: 4,
  vertexStream: 0xa0, indexStream: 0xe1,  // codec versions 0 (vertices) and 1 (indices)
};

// sRGB bytes to the linear values DRACOLoader gives for Draco's COLOR.
const srgbToLinear = Float32Array.from({ length: 256 }, (_, k) => new Color().setRGB(k / 255, 0, 0, SRGBColorSpace).r);

function meshoptError(message) {
  return new Error(`meshopt payload: ${message}`);
}

// One vertex stream of `count` elements of `stride` bytes (and a filter of MeshoptDecoder's), as bytes.
function decodeVertexStream(stream, name, count, stride, filter = 'NONE') {
  if (stream.length === 0 || stream[0] !== MOPT.vertexStream) {
    throw meshoptError(`the ${name} stream is not a version-0 meshoptimizer vertex buffer`);
  }
  const out = new Uint8Array(count * stride);
  try {
    MeshoptDecoder.decodeVertexBuffer(out, count, stride, stream, filter);
  } catch (error) {
    throw meshoptError(`the ${name} stream does not decode (${error.message})`);
  }
  return out;
}

// The header and the streams' places, checked (core/codec/meshopt_decode.cpp, read_meshopt).
function readMeshopt(bytes) {
  const data = new Uint8Array(bytes), view = new DataView(bytes);
  if (data.length < MOPT.headerBytes) {
    throw meshoptError(`${data.length} bytes, shorter than the ${MOPT.headerBytes}-byte header`);
  }
  if (String.fromCharCode(...data.subarray(0, 4)) !== MOPT.magic) throw meshoptError('the magic is not "MOPT"');
  if (data[4] !== MOPT.version) throw meshoptError(`version ${data[4]}; this viewer reads version ${MOPT.version}`);
  const flags = data[5];
  const normals = (flags & MOPT.hasNormals) !== 0, wide = (flags & MOPT.wideNormals) !== 0;
  if ((flags & ~(MOPT.hasNormals | MOPT.hasColors | MOPT.wideNormals)) !== 0 || (wide && !normals)) {
    throw meshoptError(`flags 0x${flags.toString(16)} are not a valid combination`);
  }
  const p = {
    colors: (flags & MOPT.hasColors) !== 0, positionBits: data[6], normalBits: data[7],
    normalStride: normals ? (wide ? 8 : 4) : 0,
    vertexCount: view.getUint32(8, true), triangleCount: view.getUint32(12, true),
    origin: [view.getFloat32(16, true), view.getFloat32(20, true), view.getFloat32(24, true)],
    step: view.getFloat32(28, true),
  };
  if (p.positionBits < 1 || p.positionBits > 16) throw meshoptError(`position_bits ${p.positionBits} outside 1..16`);
  if (normals) {
    const [lowest, highest] = wide ? [9, 16] : [2, 8];
    if (p.normalBits < lowest || p.normalBits > highest) {
      throw meshoptError(`normal_bits ${p.normalBits} outside ${lowest}..${highest} for ${p.normalStride}-byte normals`);
    }
  } else if (p.normalBits !== 0) {
    throw meshoptError(`normal_bits ${p.normalBits} without normals`);
  }
  if (p.vertexCount === 0 || p.triangleCount === 0) {
    throw meshoptError(`${p.vertexCount} vertices and ${p.triangleCount} triangles: neither may be 0`);
  }
  const top = ((1 << p.positionBits) - 1) * p.step;
  if (!(p.step >= 0) || !p.origin.every((o) => Number.isFinite(o + top))) {
    throw meshoptError('the grid of the positions (origin and step) is not finite, or its step is negative');
  }
  let at = MOPT.headerBytes;
  const nextStream = (name) => {
    if (data.length - at < 4) throw meshoptError(`ends at byte ${data.length} before the length of the ${name} stream`);
    const length = view.getUint32(at, true);
    at += 4;
    if (length > data.length - at) {
      throw meshoptError(`the ${name} stream's ${length} bytes at byte ${at} run past the end (${data.length} bytes)`);
    }
    at += length;
    return data.subarray(at - length, at);
  };
  p.positions = nextStream('positions');
  if (normals) p.normals = nextStream('normals');
  if (p.colors) p.colours = nextStream('colours');
  p.triangles = nextStream('triangles');
  if (at !== data.length) throw meshoptError(`${data.length - at} bytes follow the last stream`);
  // A vertex stream spends at least a byte on every 8 vertices, an index stream one per triangle and 17.
  if (Math.floor(p.vertexCount / 8) > p.positions.length) {
    throw meshoptError(`${p.vertexCount} vertices cannot fit in a ${p.positions.length}-byte positions stream`);
  }
  if (p.triangleCount + 17 > p.triangles.length) {
    throw meshoptError(`${p.triangleCount} triangles cannot fit in a ${p.triangles.length}-byte triangles stream`);
  }
  return p;
}

async function decodeMeshopt(bytes) {
  await MeshoptDecoder.ready;
  const p = readMeshopt(bytes);
  const n = p.vertexCount;
  const geometry = new BufferGeometry();

  // Positions: u16 x, y, z, 0 on the grid origin + q · step.
  const stored = new Uint16Array(decodeVertexStream(p.positions, 'positions', n, 8).buffer);
  const highest = (1 << p.positionBits) - 1;
  const positions = new Float32Array(3 * n);
  for (let i = 0; i < n; ++i) {
    if (stored[4 * i] > highest || stored[4 * i + 1] > highest || stored[4 * i + 2] > highest || stored[4 * i + 3] !== 0) {
      throw meshoptError(`position ${i} is not three ${p.positionBits}-bit coordinates and a zero`);
    }
    for (let k = 0; k < 3; ++k) positions[3 * i + k] = p.origin[k] + stored[4 * i + k] * p.step;
  }
  geometry.setAttribute('position', new BufferAttribute(positions, 3));

  // Normals: octahedral, unfolded by MeshoptDecoder's filter into signed normalized x, y, z (and the
  // fourth component, 0) of the stored width.
  if (p.normals) {
    const unfolded = decodeVertexStream(p.normals, 'normals', n, p.normalStride, 'OCTAHEDRAL');
    const [components, one] = p.normalStride === 8 ? [new Int16Array(unfolded.buffer), 32767] : [new Int8Array(unfolded.buffer), 127];
    const normals = new Float32Array(3 * n);
    for (let i = 0; i < n; ++i) {
      const x = components[4 * i], y = components[4 * i + 1], z = components[4 * i + 2];
      const length = Math.sqrt(x * x + y * y + z * z);
      if (!(length > one / 2)) throw meshoptError(`normal ${i} is not an octahedral ${p.normalBits}-bit vector`);
      normals[3 * i] = x / length;
      normals[3 * i + 1] = y / length;
      normals[3 * i + 2] = z / length;
    }
    geometry.setAttribute('normal', new BufferAttribute(normals, 3));
  }

  // Colours: r, g, b, 255.
  if (p.colors) {
    const rgba = decodeVertexStream(p.colours, 'colours', n, 4);
    const colours = new Float32Array(3 * n);
    for (let i = 0; i < n; ++i) {
      if (rgba[4 * i + 3] !== 255) throw meshoptError(`colour ${i} has alpha ${rgba[4 * i + 3]}, not 255`);
      for (let k = 0; k < 3; ++k) colours[3 * i + k] = srgbToLinear[rgba[4 * i + k]];
    }
    geometry.setAttribute('color', new BufferAttribute(colours, 3));
  }

  // Triangles: 3 u32 indices each, in the payload's order and winding.
  if (p.triangles[0] !== MOPT.indexStream) {
    throw meshoptError('the triangles stream is not a version-1 meshoptimizer index buffer');
  }
  const indexBytes = new Uint8Array(12 * p.triangleCount);
  try {
    MeshoptDecoder.decodeIndexBuffer(indexBytes, 3 * p.triangleCount, 4, p.triangles);
  } catch (error) {
    throw meshoptError(`the triangles stream does not decode (${error.message})`);
  }
  const index = new Uint32Array(indexBytes.buffer);
  for (let c = 0; c < index.length; ++c) {
    if (index[c] >= n) throw meshoptError(`triangle ${Math.floor(c / 3)} names vertex ${index[c]} of ${n}`);
  }
  geometry.setIndex(new BufferAttribute(index, 1));
  return geometry;
}

// The codecs a reply may name, in the order the viewer's panel lists them (the first is the default);
// `labels`: the payload can carry the distance labels.
export const CODECS = {
  draco: { label: 'Draco', decode: decodeDraco, labels: true },
  meshopt: { label: 'meshoptimizer', decode: decodeMeshopt, labels: false },
};

// The payload's bytes (an ArrayBuffer, which the decoder may take: Draco's is transferred to the
// loader's worker, so a caller that reads it afterwards hands over a copy) decoded as `codec` names them: a promise of the
// geometry, rejected with an Error for a codec this viewer does not know or a damaged payload.
export async function decodePayload(codec, bytes) {
  if (!Object.hasOwn(CODECS, codec)) throw new Error(`the reply's codec '${codec}' is not one this viewer decodes`);
  return CODECS[codec].decode(bytes);
}
