#!/usr/bin/env python3
"""Writes the seed corpora of fuzz_scene_api (native/fuzz/corpus/scene_api/) and
fuzz_part_file (native/fuzz/corpus/part_file/).

The formats are described at the top of fuzz_scene_api.cpp and
fuzz_part_file.cpp. fuzz_scene_api: one op byte, then its operands; a float is
tag 0 + 4 raw bytes, tag 1 + an index into kSpecialFloats, or tag 2 + a signed
byte / 16. fuzz_part_file: the valid part to start from, a flags byte, then
(offset, byte) edits.
Run: python3 native/fuzz/make_corpus.py
"""
import os
import struct

CORPUS = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus")
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


# Ops 13-16 are op bytes 208-211.
SIZE = {"zero": 0, "older": 1, "newer": 2, "short": 3, "current": 5}


def lobe(material, type_, color=None, roughness=None, ior=None, abbe=None, weight=None, size=None):
    fields, body = 0, b""
    for bit, value in ((1, color), (2, roughness), (4, ior), (8, abbe), (16, weight)):
        if value is not None:
            fields |= bit
            body += b"".join(f(c) for c in value) if bit == 1 else f(value)
    if size is not None:
        fields |= 32
        body += bytes([SIZE[size]])
    return bytes([208, material, type_ + 1, fields]) + body


def world_map(w, h, pixels, angle=0.0, strength=1.0, flags=0):
    return bytes([209, flags, w, h]) + bytes(pixels) + f(angle) + f(strength)


def stats_of_size(size):
    return bytes([210, 0, SIZE[size]])


def bake_of_size(size, photons=400, direct=2, bounces=4):
    return bytes([210, 1]) + struct.pack("<H", photons) + bytes([direct, bounces, SIZE[size]])


def light_of_size(size, name=2):
    return bytes([210, 2, 1, SIZE[size], name])


def csg_node_of_size(node, size, name=2):
    return bytes([210, 2, 0, node, SIZE[size], name])


def light_group(what, group, target, layer=0, mesh=0, name=2):
    """what: 1 declares a group (named by `name`), bits 1-2 pick light / mesh / world (0-2) to put into `group`."""
    return bytes([211, what]) + (bytes([name]) if what & 1 else b"") + bytes([group, target, layer, mesh])


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
    "lobes_under_world_map": material((0.3, 0.3, 0.3), (0, 0, 0)) + quad((-1, -1, 0), (2, 0, 0), (0, 2, 0), 0, 4) +
    lobe(0, 5, color=(0.04, 0.04, 0.04), roughness=0.25) + lobe(0, 1, color=(0.9, 0.6, 0.2), weight=0.5) +
    lobe(0, 2, ior=1.5, abbe=40.0, size="older") + lobe(0, 0, roughness="nan") + lobe(0, 3, size="zero") +
    world_map(4, 2, [40, 60, 90] * 8, angle=0.5, strength=2.0) + bake(1000, 4) + copy(0) + warnings(),
    "world_map_file": quad((-1, -1, 0), (2, 0, 0), (0, 2, 0), 0, 4) +
    world_map(3, 2, [64, 64, 64, 200, 100, 50] * 3, strength=1.5, flags=16) + bake(800, 2) + copy(0) +
    world_map(2, 1, [1, 2, 3, 4, 5, 6], flags=16 | 32) + world_map(0, 0, [], flags=1),
    "struct_sizes": quad((-1, -1, 0), (2, 0, 0), (0, 2, 0), 0, 4) + light(0, 100.0, matrix=[(11, 1.0)]) +
    bake_of_size("older") + stats_of_size("older") + stats_of_size("zero") + stats_of_size("newer") +
    bake_of_size("short") + light_of_size("zero") + light_of_size("current") + csg_node_of_size(1, "short") +
    csg_node_of_size(0, "current") + bake_of_size("current") + stats_of_size("current"),
    "light_groups": material((0.7, 0.7, 0.7), (0, 0, 0)) + quad((-1, -1, 0), (2, 0, 0), (0, 2, 0), 0, 4) +
    light(0, 100.0, matrix=[(11, 1.0)]) + world((0.2, 0.3, 0.4)) + light_group(1, 1, 0) +
    light_group(1 | 4, 2, 0, name=1) + light_group(4, 1, 0) + bake(1500, 4) + light_group(6, 0, 0, 1, 0) +
    light_group(6, 0, 0, 2, 0) + light_group(2, 3, 9, 0, 1),
}


def part(start, flags=0, edits=(), resize=None):
    body = bytes([start, flags | (4 if resize is not None else 0)])
    if resize is not None:
        body += struct.pack("<H", resize)
    return body + b"".join(struct.pack("<HB", at, value) for at, value in edits)


# Header offsets (transport/farm/partial_file.cpp): 80 shard count, 92 texel count, 124 segment count, 404 kind,
# 428 range end.
PART_SEEDS = {
    "photons": part(0),
    "direct": part(1),
    "gather": part(2),
    "photons_as_direct_resealed": part(0, 3, [(404, 1)]),
    # a find: 2^31 shards claimed, one given (the merge sized a table by the count)
    "shard_count_huge_resealed": part(0, 2, [(83, 0x7F)]),
    "texel_count_resealed": part(0, 3, [(92, 0xFF)]),
    "segments_resealed": part(0, 3, [(124, 3)]),
    "direct_range_resealed": part(1, 3, [(428, 0x10)]),
    "direct_sums_resealed": part(1, 1, [(520, 0xFF), (521, 0xFF), (527, 0x7F)]),
    "gather_damaged": part(2, 0, [(600, 1)]),
    "photons_truncated": part(0, 0, resize=300),
    "raw_magic": bytes([3, 0]) + b"PLMPART\0" + bytes([4, 0, 0, 0, 0, 2, 0, 0]) + bytes(40),
}

for folder, seeds in (("scene_api", SEEDS), ("part_file", PART_SEEDS)):
    os.makedirs(os.path.join(CORPUS, folder), exist_ok=True)
    for name, data in seeds.items():
        with open(os.path.join(CORPUS, folder, name), "wb") as fh:
            fh.write(data)
        print(f"{folder}/{name}: {len(data)} bytes")
