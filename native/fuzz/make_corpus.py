#!/usr/bin/env python3
"""Writes the seed corpus of fuzz_scene_api (native/fuzz/corpus/scene_api/).

The format is described at the top of fuzz_scene_api.cpp: one op byte, then
its operands; a float is tag 0 + 4 raw bytes, tag 1 + an index into
kSpecialFloats, or tag 2 + a signed byte / 16.
Run: python3 native/fuzz/make_corpus.py
"""
import os
import struct

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus", "scene_api")
SPECIAL = {"nan": 20, "inf": 22, "-inf": 23, "1e30": 14, "3.4e38": 16, "1e-45": 9}


def f(v):
    if isinstance(v, str):
        return bytes([1, SPECIAL[v]])
    return bytes([0]) + struct.pack("<f", v)


def material(albedo, emission, name=2):
    return bytes([0, name]) + b"".join(f(v) for v in albedo) + b"".join(f(v) for v in emission) + bytes([0])


def quad(o, a, b, mat=0, res=4):
    return bytes([2]) + b"".join(f(v) for v in (*o, *a, *b)) + bytes([mat, res - 1])


def mesh(pos, idx, uv, mats, w_sel, h_sel, flags=31, name=2):
    vc, tc = len(pos) // 3, len(idx) // 3
    return (bytes([1, name, vc, tc]) + b"".join(f(v) for v in pos) + bytes(idx) + bytes([flags]) +
            b"".join(f(v) for v in uv) + bytes(mats) + bytes([w_sel, h_sel]))


def light(type_, power=None, color=None, matrix=(), size=None, name=2):
    fields = 0
    body = b""
    if power is not None:
        fields |= 1
        body += f(power)
    if size is not None:
        fields |= 8
        body += f(size[0]) + f(size[1])
    if color is not None:
        fields |= 32
        body += b"".join(f(c) for c in color)
    body += bytes([len(matrix)]) + b"".join(bytes([i]) + f(v) for i, v in matrix)
    return bytes([3, type_ + 1, fields]) + body + bytes([name])


def subdiv(pos, sizes, idx, uv, mats, creases=(), level=2, flags=63, w_sel=4, h_sel=4, name=2):
    body = bytes([11, name, len(pos) // 3, len(sizes)]) + b"".join(f(v) for v in pos)
    body += bytes([s - 2 for s in sizes]) + bytes(idx) + b"".join(f(v) for v in uv) + bytes(mats)
    body += bytes([len(creases)]) + b"".join(bytes([a, b]) + f(w) for a, b, w in creases)
    return body + bytes([flags, level, w_sel, h_sel])


def cube_cage():
    pos = [1, 1, 1, 1, 1, -1, 1, -1, 1, 1, -1, -1, -1, 1, 1, -1, 1, -1, -1, -1, 1, -1, -1, -1]
    idx = [0, 4, 6, 2, 3, 2, 6, 7, 7, 6, 4, 5, 5, 1, 3, 7, 1, 0, 2, 3, 5, 4, 0, 1]
    uv = []
    for k in range(6):  # one tile of a 3 x 2 atlas per face
        u0, v0 = (k % 3) / 3 + 0.01, (k // 3) / 2 + 0.01
        uv += [u0, v0, u0 + 0.31, v0, u0 + 0.31, v0 + 0.48, u0, v0 + 0.48]
    return pos, [4] * 6, idx, uv, [0] * 6


def world(rgb):
    return bytes([4]) + b"".join(f(v) for v in rgb) + bytes([1])


def bake(photons=1500, bounces=8, seed=1, threads=1, flags=0, direct=2, steer=None):
    body = bytes([5]) + struct.pack("<H", photons) + bytes([bounces]) + struct.pack("<I", seed)
    body += bytes([threads, flags | (2 if steer else 0), direct])
    if steer:
        body += f(steer[0]) + f(steer[1])
    return body + bytes([3])


def copy(mesh_id, which=15):
    return bytes([6, mesh_id, which])


def exr(mesh_id, where=0):
    return bytes([7, mesh_id, where])


def warnings():
    return bytes([8, 1])


SEEDS = {
    "point_over_quad": material((0.8, 0.8, 0.8), (0, 0, 0)) + quad((-1, -1, 0), (2, 0, 0), (0, 2, 0), 0, 8) +
    light(0, 100.0, matrix=[(11, 1.0)]) + bake() + copy(0) + exr(0) + warnings(),
    "furnace_quads": material((0.99, 0.99, 0.99), (1, 1, 1)) + quad((0, 0, 0), (1, 0, 0), (0, 1, 0), 0, 4) +
    quad((0, 0, 1), (0, 1, 0), (1, 0, 0), 0, 4) + bake(2000, 16) + copy(1) + warnings(),
    "sun_degenerate": mesh([0, 0, 0, 1, 0, 0, 1, 1, 0, 0.5, 0, 0], [0, 1, 2, 0, 3, 1],
                           [0, 0, 1, 0, 1, 1, 0, 0, 0.5, 0, 1, 0], [0, 0], 4, 4, flags=15) +
    light(2, 2.0, matrix=[(6, 0.5)]) + bake(1000, 0, direct=1) + copy(0) + exr(0, 1) + warnings(),
    "area_world_steered": quad((0, 0, 0), (3, 0, 0), (0, 3, 0), 0, 2) + light(3, 50.0, size=(0.5, 0.25),
                                                                              matrix=[(11, 2.0)]) +
    world((0.2, 0.3, 0.4)) + bake(800, 4, steer=(0.05, 0.01)) + copy(0, 3) + exr(0) + bytes([9]),
    "bad_values": material(("nan", 0.5, 0.5), (0, 0, 0)) + mesh([0, 0, "inf", 1, 0, 0, 0, 1, 0], [0, 1, 3],
                                                                 [0, 0, 1, 0, 0, 1], [0], 8, 4) +
    light(1, "nan", color=("1e30", 1, 1), matrix=[(3, "inf")]) + world(("-inf", 0, 0)) + bake(0) +
    quad(("3.4e38", 0, 0), (1, 0, 0), (0, 1, 0)) + bake(10, 1, flags=1) + exr(3, 3),
    "subdiv_cube_under_sky": material((0.8, 0.8, 0.8), (0, 0, 0)) +
    subdiv(*cube_cage(), creases=[(0, 4, 1.0), (4, 6, 0.5)]) + world((0.5, 0.5, 0.5)) +
    light(5, size=(1.0, 1.0), matrix=[(11, 3.0)]) + bake(1000, 4) + copy(0) + warnings(),
}

os.makedirs(OUT, exist_ok=True)
for name, data in SEEDS.items():
    with open(os.path.join(OUT, name), "wb") as fh:
        fh.write(data)
    print(f"{name}: {len(data)} bytes")
