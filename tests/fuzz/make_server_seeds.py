#!/usr/bin/env python3
"""Writes the hand-made seeds of the server fuzz targets (tests/fuzz/corpus/server_stream and
server_messages): whole sessions as a client sends them. server_stream seeds are framed byte
streams (PROTOCOL.md, "Framing"); server_messages seeds are chunks of a flags byte (bit 0: binary),
a 16-bit little-endian length and the message (fuzz_server_messages.cpp). Usage: make_server_seeds.py
[CORPUS_DIR]; libFuzzer's merged finds sit beside these files and are left alone."""
import json
import os
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
    # Once crashed the server: the error message quoting the model name was not UTF-8.
    "model-info-invalid-utf8": [b'{"type":"model_info","id":1,"model":"\xff\xfe"}'],
}


def frame(json_text, payload=b""):
    return struct.pack("<II", len(json_text), len(payload)) + json_text + payload


def message(text, binary=False):
    return struct.pack("<BH", 1 if binary else 0, len(text)) + text


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


if __name__ == "__main__":
    main()
