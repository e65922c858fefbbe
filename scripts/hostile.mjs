#!/usr/bin/env node
// Hostile traffic against a running mtlod-server, for scripts/soak.sh: for --duration seconds,
// --clients concurrent loops each open a connection and misbehave in one of ten ways (mutated and
// random frames, a 2 GiB frame header, invalid UTF-8, half-sent frames, resets mid-request, idle
// sockets, garbage and idle sockets on the HTTP port, WebSocket upgrades that send junk). Only
// loopback addresses are accepted as targets. Prints one JSON line of counts at the end.
//   node scripts/hostile.mjs --port P [--http-port H] [--duration S] [--clients N] [--seed N] [--source A]
import net from 'node:net';

const args = Object.fromEntries(
  process.argv.slice(2).reduce((pairs, a, i, all) => (a.startsWith('--') ? [...pairs, [a.slice(2), all[i + 1]]] : pairs), []));
const host = args.host ?? '127.0.0.1';
// Another loopback address than the normal load's, so the server sees a client of its own.
const source = args.source ?? '127.0.0.2';
if (!/^127\.\d+\.\d+\.\d+$|^localhost$|^::1$/.test(host)) throw new Error(`--host ${host}: loopback addresses only`);
const port = Number(args.port);
const httpPort = args['http-port'] ? Number(args['http-port']) : 0;
const durationMs = 1000 * Number(args.duration ?? 60);
const clients = Number(args.clients ?? 4);
let seed = Number(args.seed ?? 1) >>> 0;
if (!port) throw new Error('--port is required');

// xorshift32: reproducible runs for a seed.
function random() {
  seed ^= seed << 13; seed >>>= 0;
  seed ^= seed >>> 17;
  seed ^= seed << 5; seed >>>= 0;
  return seed / 4294967296;
}
const pick = (n) => Math.floor(random() * n);

function frame(json) {
  const body = Buffer.isBuffer(json) ? json : Buffer.from(json);
  const header = Buffer.alloc(8);
  header.writeUInt32LE(body.length, 0);
  header.writeUInt32LE(0, 4);
  return Buffer.concat([header, body]);
}
const extract = JSON.stringify({
  type: 'extract', id: 5, model: 'bunny',
  camera: { view: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -0.1, -0.4, 1],
            projection: [1.8, 0, 0, 0, 0, 2.4, 0, 0, 0, 0, -1.002, -1, 0, 0, -0.02, 0] },
  grid: [128, 96], error: { value: 1, unit: 'pixels' },
});
function randomBytes(n) {
  const b = Buffer.alloc(n);
  for (let i = 0; i < n; ++i) b[i] = pick(256);
  return b;
}

const counts = { sessions: 0, replies: 0, refused_or_closed: 0, errors: 0 };

// One misbehaving session; resolves when the socket is gone (by either side) or after a cap.
function session(kind) {
  return new Promise((resolve) => {
    const toHttp = kind >= 7 && httpPort;
    const socket = net.connect({ host, port: toHttp ? httpPort : port, localAddress: source });
    let done = false;
    const finish = () => { if (!done) { done = true; clearTimeout(cap); socket.destroy(); resolve(); } };
    const cap = setTimeout(finish, 15000);
    socket.on('data', () => { counts.replies++; });
    socket.on('error', () => { counts.errors++; finish(); });
    socket.on('close', () => { counts.refused_or_closed++; finish(); });
    socket.on('connect', () => {
      counts.sessions++;
      switch (toHttp ? kind : kind % 7) {
        case 0: {  // a valid request with bytes overwritten
          const b = Buffer.from(extract);
          for (let k = 1 + pick(4); k > 0; --k) b[pick(b.length)] = pick(256);
          socket.write(frame(b));
          setTimeout(() => socket.end(), 200);
          break;
        }
        case 1: socket.write(randomBytes(pick(300))); socket.end(); break;
        case 2: socket.write(Buffer.from([0xff, 0xff, 0xff, 0x7f, 0xff, 0xff, 0xff, 0x7f])); break;
        case 3:
          socket.write(frame(Buffer.concat([Buffer.from('{"type":"model_info","id":1,"model":"'),
                                            Buffer.from([0xff, 0xfe, 0xc3]), Buffer.from('"}')])));
          setTimeout(() => socket.end(), 200);
          break;
        case 4: {  // half a frame, then silence until the read deadline
          const f = frame(extract);
          socket.write(f.subarray(0, 1 + pick(f.length - 1)));
          break;
        }
        case 5: socket.write(frame(extract)); socket.resetAndDestroy(); break;
        case 6: break;  // idle until the first-frame deadline
        case 7: socket.write(`GET /${randomBytes(pick(200)).toString('latin1')} HTTP/1.1\r\n\r\n`); break;
        case 8: break;  // idle HTTP
        default:  // a WebSocket upgrade, then junk that is not a WebSocket frame
          socket.write('GET /ws HTTP/1.1\r\nHost: 127.0.0.1\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n' +
                       'Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n');
          setTimeout(() => socket.write(randomBytes(64)), 50);
      }
    });
  });
}

const end = Date.now() + durationMs;
await Promise.all(Array.from({ length: clients }, async () => {
  while (Date.now() < end) await session(pick(httpPort ? 10 : 7));
}));
console.log(JSON.stringify(counts));
