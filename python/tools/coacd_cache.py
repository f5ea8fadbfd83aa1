#!/usr/bin/env python3
"""Fill sage3d's hull cache with CoACD decompositions (the paper's decomposer).

sage3d decomposes meshes in process with V-HACD; CoACD has no Rust port, so its hulls are made
offline here and written in the same cache format, under the keys sage3d computes:

    sage3d physics pending SCENE --backend coacd [--threshold 0.05] [--max-hulls 32] --out todo.json
    python python/tools/coacd_cache.py todo.json          # needs `pip install coacd`
    sage3d physics build SCENE --backend coacd [same settings]

Cache file (little endian): b"SAGEHULL", u32 version 1, 16-byte key (the 128-bit key as a
little-endian integer), u32 part count, then per part u32 vertex count n, u32 triangle count m,
n x 3 float32 positions, m x 3 uint32 indices. Files are written to a temporary name and renamed.
"""

import argparse
import json
import math
import os
import struct
import sys

MAGIC = b"SAGEHULL"
VERSION = 1


def encode(key_hex, parts):
    """The cache file bytes for `parts`, a list of (vertices, triangles)."""
    out = bytearray(MAGIC)
    out += struct.pack("<I", VERSION)
    out += int(key_hex, 16).to_bytes(16, "little")
    out += struct.pack("<I", len(parts))
    for vertices, triangles in parts:
        out += struct.pack("<II", len(vertices), len(triangles))
        for v in vertices:
            out += struct.pack("<3f", *map(float, v))
        for t in triangles:
            out += struct.pack("<3I", *map(int, t))
    return bytes(out)


def is_whole_entry(path, key_hex):
    """Whether `path` holds a whole cache file of `key_hex`, by the checks sage3d reads it
    with: a file cut short, of another version or key, with trailing bytes, a coordinate that
    is not finite or a triangle index past its part's vertices is made again (sage3d lists it
    as pending)."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except FileNotFoundError:
        return False
    head = len(MAGIC) + 4 + 16 + 4
    if len(data) < head or data[: len(MAGIC)] != MAGIC:
        return False
    (version,) = struct.unpack_from("<I", data, len(MAGIC))
    if version != VERSION or data[len(MAGIC) + 4 : len(MAGIC) + 20] != int(key_hex, 16).to_bytes(16, "little"):
        return False
    (parts,) = struct.unpack_from("<I", data, head - 4)
    at = head
    for _ in range(parts):
        if at + 8 > len(data):
            return False
        nv, nt = struct.unpack_from("<II", data, at)
        at += 8
        end = at + 12 * (nv + nt)
        if end > len(data):
            return False
        coords = struct.unpack_from(f"<{3 * nv}f", data, at)
        indices = struct.unpack_from(f"<{3 * nt}I", data, at + 12 * nv)
        if not all(math.isfinite(c) for c in coords) or any(i >= nv for i in indices):
            return False
        at = end
    return at == len(data)


def write_atomic(path, data):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = f"{path}.tmp-{os.getpid()}"
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        # A failed or interrupted write leaves no temporary file beside the cache's entries.
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("pending", help="JSON written by `sage3d physics pending --backend coacd`")
    ap.add_argument("--seed", type=int, default=0, help="CoACD's random seed")
    args = ap.parse_args(argv)
    with open(args.pending) as f:
        todo = json.load(f)
    if not todo["decomposer"].startswith("coacd;"):
        sys.exit(f"{args.pending}: decomposer is {todo['decomposer']!r}; run pending with --backend coacd")
    import coacd  # noqa: PLC0415 (optional dependency, only needed to decompose)
    import numpy as np  # noqa: PLC0415

    settings = todo["settings"]
    for i, m in enumerate(todo["meshes"]):
        # Each entry is written as soon as it is done, so a rerun after a crash resumes.
        if is_whole_entry(m["cache_file"], m["key"]):
            continue
        mesh = coacd.Mesh(np.asarray(m["vertices"], dtype=np.float64), np.asarray(m["triangles"], dtype=np.int32))
        parts = coacd.run_coacd(
            mesh,
            threshold=settings["threshold"],
            max_convex_hull=settings["max_hulls"] if settings["max_hulls"] > 0 else -1,
            seed=args.seed,
        )
        write_atomic(m["cache_file"], encode(m["key"], parts))
        print(f"[{i + 1}/{len(todo['meshes'])}] instance {m['instance']}: {len(parts)} hulls")


if __name__ == "__main__":
    main()
