#!/usr/bin/env python3
"""Writes the hand-made seeds of the server fuzz targets (tests/fuzz/corpus/...): whole sessions as
a client sends them. server_stream seeds are framed byte streams (PROTOCOL.md, "Framing"), which
process_tcp reads too; server_messages seeds are chunks of a flags byte (bit 0: binary), a 16-bit
little-endian length and the message (fuzz_server_messages.cpp), which process_websocket reads too;
process_http seeds are HTTP/1.1 requests; process_tls seeds are a mode byte and a TLS ClientHello
(even) or a framed byte stream (odd; fuzz_process_tls.cpp). Usage: make_server_seeds.py
[CORPUS_DIR]; libFuzzer's merged finds sit beside these files and are left alone."""
import json
import os
import ssl
import struct
import sys

CAMERA = {"view": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, -3, 1],
          "projection": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -1, -1, 0, 0, -0.2, 0],
          "viewport": [800, 600]}


def request(kind, id, **fields):
    return json.dumps({"type": kind, "id": id, **fields}, separators=(",", ":")).encode()


def extract(id, **fields):
    defaults = {"model": "bunny", "camera": CAMERA, "grid": [64, 48], "error": {"value": 1, "unit": "pixels"}}
    return request("extract", id, **{**defaults, **fields})


SESSIONS = {
    "session": [
        request("hello", 1, version=1, client="fuzz"),
        request("list_models", 2),
        request("model_info", 3, model="bunny"),
        extract(4, criteria={"silhouette": {"distance": 2, "factor": 0},
                             "focus": [{"x": 0.5, "y": 0.5, "distance": 10, "factor": 0.2}]},
                budget=2000, attributes={"normals": True, "labels": True}, draco={"method": "edgebreaker"}),
        request("gaze", 5, x=0.3, y=0.4),
        request("gaze", 6, x=0.6, y=0.5, distance=10, factor=0.5),
        request("gaze", 7, x=0.7, y=0.2),
        request("cancel", 8, target=7),
        request("stats", 9),
        request("ping", 10),
    ],
    "delta": [
        extract(1, delta=True, criteria={"focus": [{"x": 0.4, "y": 0.5}]}),
        request("gaze", 2, x=0.6, y=0.5),
        request("gaze", 3, x=0.2, y=0.8, factor=0.1),
        extract(4, error=0.05),
        extract(5, delta=True, draco={"method": "sequential", "entropy_coding": False}),
        request("gaze", 6, x=0.5, y=0.5),
    ],
    "pipeline": [extract(i, budget=100 * i) for i in range(1, 7)] + [
        request("cancel", 7, target=5),
        request("cancel", 8, target=99),
        request("ping", 9),
    ],
    "criteria": [
        extract(1, criteria={"neglect": [{"x": 0.9, "y": 0.9, "distance": 60, "factor": 4}], "falloff": "foveal",
                             "distance": "chamfer-3-4", "units": "chamfer", "internal_silhouettes": True,
                             "frustum_factor": 2, "backface_factor": 3}),
        extract(2, error=0.01, grid=[1, 1], criteria={"silhouette": True, "distance": "euclidean"}),
        extract(3, camera={**CAMERA, "viewport": [16384, 1]}, grid=[64, 1],
                criteria={"focus": [{"x": 1, "y": 0}], "falloff": "smoothstep", "distance": "chessboard"}),
        extract(4, error=0, budget=3000, draco={"speed": 0, "position_bits": 16, "normal_bits": 2},
                attributes={"normals": True}),
        extract(5, criteria={"falloff": "linear", "distance": "city-block",
                             "focus": [{"x": 0.1, "y": 0.1}, {"x": 0.9, "y": 0.1}]}),
    ],
    # Each refused with its documented code (PROTOCOL.md, "Malformed requests and their replies").
    "malformed": [
        b'{"type":"ping","id":1',
        b'{"type":"extract","id":2,"error":1e999}',
        b'{"type":"ping"}',
        b'{"type":"ping","id":-4}',
        b'{"type":42,"id":5}',
        b'{"type":"teleport","id":6}',
        b'{"type":"hello","id":7,"version":2}',
        b'{"type":"ping","id":8,"colour":"red"}',
        b'{"type":"model_info","id":9,"model":"no-such-model"}',
        request("gaze", 10, x=0.5, y=0.5),
        extract(11, grid=[5000, 5000]),
        extract(12, budget=99000000),
        extract(13, delta=True, draco={"method": "edgebreaker"}),
        extract(14, camera={**CAMERA, "projection": [0] * 16}),
        request("cancel", 15, target=1.5),
        b"[]",
        b"\x00\xff",
    ],
    # Draco's cost doubles with every bit of entropy-coded attributes, and it refuses 1-bit normals:
    # found by these targets, now refused by the parser's ranges; the last is the most allowed.
    "draco-bits": [
        extract(1, error=0, draco={"position_bits": 30}),
        extract(2, error=0, attributes={"normals": True}, draco={"normal_bits": 30}),
        extract(3, error=0, attributes={"normals": True}, draco={"normal_bits": 1}),
        extract(4, error=0, attributes={"normals": True}, draco={"position_bits": 20, "normal_bits": 16}),
    ],
    # Both codecs: the session's from its hello, one named per extract, full and delta replies, and
    # what meshopt refuses (labels).
    "codecs": [
        request("hello", 1, version=1, client="fuzz", codec="meshopt"),
        extract(2, attributes={"normals": True}, quantization={"position_bits": 12, "normal_bits": 10}),
        extract(3, delta=True, criteria={"focus": [{"x": 0.4, "y": 0.5}]}),
        request("gaze", 4, x=0.6, y=0.5),
        extract(5, codec="draco", delta=True),
        extract(6, codec="meshopt", attributes={"labels": True}),
        extract(7, codec="zstd"),
    ],
    # Once crashed the server: the error message quoting the model name was not UTF-8.
    "model-info-invalid-utf8": [b'{"type":"model_info","id":1,"model":"\xff\xfe"}'],
}


def frame(json_text, payload=b""):
    return struct.pack("<II", len(json_text), len(payload)) + json_text + payload


def message(text, binary=False):
    return struct.pack("<BH", 1 if binary else 0, len(text)) + text


def http(target, method="GET", headers=(), body=b""):
    head = [f"{method} {target} HTTP/1.1", "Host: 127.0.0.1", *headers]
    if body:
        head.append(f"Content-Length: {len(body)}")
    return ("\r\n".join(head) + "\r\n\r\n").encode() + body


UPGRADE = ("Upgrade: websocket", "Connection: Upgrade", "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==",
           "Sec-WebSocket-Version: 13")

HTTP = {
    "health": http("/health"),
    "metrics-then-health": http("/metrics") + http("/health"),
    "viewer-files": http("/") + http("/viewer.js") + http("/three/build/three.module.js", headers=("Connection: close",)),
    "post": http("/health", method="POST", body=b'{"type":"ping","id":1}'),
    "escape": http("/../../etc/passwd") + http("/three/../../README.md") + http("/%2e%2e/CMakeLists.txt"),
    "http10": b"GET /health HTTP/1.0\r\n\r\n",
    "upgrade": http("/ws", headers=UPGRADE),
    "upgrade-elsewhere": http("/viewer.js", headers=UPGRADE),
    "chunked": http("/health", headers=("Transfer-Encoding: chunked",)) [:-2] + b"\r\n4\r\nabcd\r\n0\r\n\r\n",
    "bad-then-good": b"GET /health HTTP/9.9\r\n\r\n" + http("/health"),
}


def client_hello():
    """A TLS ClientHello as Python's OpenSSL sends it (its random bytes differ on every call)."""
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)
    context.check_hostname = False
    context.verify_mode = ssl.CERT_NONE
    incoming, outgoing = ssl.MemoryBIO(), ssl.MemoryBIO()
    try:
        context.wrap_bio(incoming, outgoing).do_handshake()
    except ssl.SSLWantReadError:
        pass
    return outgoing.read()


def write(folder, name, data):
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, name + ".bin"), "wb") as f:
        f.write(data)


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "corpus")
    stream, messages = os.path.join(root, "server_stream"), os.path.join(root, "server_messages")
    for name, requests in SESSIONS.items():
        write(stream, name, b"".join(frame(r) for r in requests))
        write(messages, name, b"".join(message(r) for r in requests))
    ping = request("ping", 1)
    # Streams that break: an empty JSON part, a body over max_frame_bytes, a frame cut short.
    write(stream, "bad-frame", frame(ping) + struct.pack("<II", 0, 0) + frame(ping))
    write(stream, "oversized-frame", frame(ping) + struct.pack("<II", 100000, 0))
    write(stream, "truncated", frame(ping) + frame(SESSIONS["session"][3])[:200])
    write(stream, "payload", frame(ping, b"\x01\x02\x03") + frame(request("ping", 2)))
    # Binary messages: whole frames, one whose header does not announce what follows, one too big.
    write(messages, "binary", b"".join(message(frame(r), binary=True) for r in SESSIONS["delta"]))
    write(messages, "bad-binary", message(frame(ping), True) + message(frame(ping)[:-1], True))
    write(messages, "too-big", message(ping) + message(b" " * 5000) + message(ping))
    # Text that is not UTF-8 breaks the WebSocket protocol (process_websocket: the server closes).
    write(messages, "not-utf8", message(ping) + message(b'{"type":"ping","id":2}\xc3\x28'))
    for name, data in HTTP.items():
        write(os.path.join(root, "process_http"), name, data)
    tls = os.path.join(root, "process_tls")
    # Kept once made: a new ClientHello differs in its random bytes only.
    if not os.path.exists(os.path.join(tls, "client-hello.bin")):
        write(tls, "client-hello", b"\x00" + client_hello())
    write(tls, "session", b"\x01" + b"".join(frame(r) for r in SESSIONS["session"]))
    write(tls, "codecs", b"\x01" + b"".join(frame(r) for r in SESSIONS["codecs"]))
    write(tls, "bad-frame", b"\x01" + frame(ping) + struct.pack("<II", 0, 0) + frame(ping))


if __name__ == "__main__":
    main()
