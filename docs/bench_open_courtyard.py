"""An open sunlit courtyard of many objects as a scene file, baked with the CLI.

    /usr/bin/python3 docs/bench_open_courtyard.py --out /tmp/court [--objects 128] [--segments 64]
        [--target 0.05] [--photons 50000000] [--seed 1] [--no-bake] [--smooth]

Writes DIR/scene.json (docs/scene-file.md) and one OBJ per object: a 24 x 24 m ground, four 3 m
walls facing in, and --objects spheres of radius 0.5 m resting on the ground in a grid (UV spheres
of --segments rings x 2 --segments sides: 64 gives 16 k triangles, 128 of them 2.1 M, about the
issue's 128 subdivided monkeys), each with a 64 x 64 lightmap; a sun of 4 W/m^2 at 45 degrees and a
sky (0.3, 0.4, 0.6), the open benchmark scene's lights. Then runs `build/bin/photonlm bake` with the
target error and prints the time, the reported error and the photon hits per emitted photon from
its report.json.
"""
import argparse
import json
import math
import os
import subprocess
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
RES = 64


def write_obj(path, pos, tris, uvs):
    """OBJ with one vt per triangle corner (face-varying lightmap UVs)."""
    with open(path, "w") as f:
        f.write("".join("v %.6f %.6f %.6f\n" % tuple(p) for p in pos))
        f.write("".join("vt %.6f %.6f\n" % tuple(t) for t in uvs.reshape(-1, 2)))
        f.write("".join("f %d/%d %d/%d %d/%d\n" % (a + 1, 3 * i + 1, b + 1, 3 * i + 2, c + 1, 3 * i + 3)
                        for i, (a, b, c) in enumerate(tris)))


def quad(corners):
    """Two triangles over four corners (counter-clockwise seen from the front), UVs inside a 1.5-texel margin."""
    m = 1.5 / RES
    uv = np.array([[m, m], [1 - m, m], [1 - m, 1 - m], [m, 1 - m]])
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    return np.array(corners, float), tris, uv[tris]


def sphere(center, radius, rings):
    """UV sphere; lightmap UVs are longitude x latitude inside a 1.5-texel margin."""
    sides = 2 * rings
    m = 1.5 / RES
    pos, tris, uvs = [], [], []
    for i in range(rings + 1):
        th = math.pi * i / rings
        for j in range(sides + 1):
            ph = 2 * math.pi * j / sides
            pos.append([center[0] + radius * math.sin(th) * math.cos(ph), center[1] + radius * math.sin(th) * math.sin(ph),
                        center[2] + radius * math.cos(th)])
    idx = lambda i, j: i * (sides + 1) + j
    uv_of = lambda i, j: [m + (1 - 2 * m) * j / sides, 1 - m - (1 - 2 * m) * i / rings]
    for i in range(rings):
        for j in range(sides):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            if i > 0:
                tris.append([a, b, d])
                uvs.append([uv_of(i, j), uv_of(i + 1, j), uv_of(i, j + 1)])
            if i < rings - 1:
                tris.append([b, c, d])
                uvs.append([uv_of(i + 1, j), uv_of(i + 1, j + 1), uv_of(i, j + 1)])
    return np.array(pos), np.array(tris), np.array(uvs)


def build(out, objects, rings, smooth, settings):
    os.makedirs(out, exist_ok=True)
    half, height = 12.0, 3.0
    meshes = []
    # Ground (facing up) and walls (facing in).
    parts = {"ground": quad([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]])}
    for k, (x, y, dx, dy) in enumerate([(-half, -half, 1, 0), (half, -half, 0, 1), (half, half, -1, 0), (-half, half, 0, -1)]):
        a = [x, y, 0]
        b = [x + 2 * half * dx, y + 2 * half * dy, 0]
        parts["wall%d" % k] = quad([b, a, [a[0], a[1], height], [b[0], b[1], height]])  # facing in
    for name, (pos, tris, uvs) in parts.items():
        write_obj(os.path.join(out, name + ".obj"), pos, tris, uvs)
        meshes.append({"name": name, "obj": name + ".obj", "material": "ground" if name == "ground" else "wall",
                       "lightmap_resolution": RES})
    cols = int(math.ceil(math.sqrt(2 * objects)))
    rows = int(math.ceil(objects / cols))
    for k in range(objects):
        r, c = divmod(k, cols)
        x = -half + 2.0 + (2 * half - 4.0) * (c + 0.5) / cols
        y = -half + 2.0 + (2 * half - 4.0) * (r + 0.5) / max(rows, 1)
        pos, tris, uvs = sphere([x, y, 0.5], 0.5, rings)
        name = "object%03d" % k
        write_obj(os.path.join(out, name + ".obj"), pos, tris, uvs)
        mesh = {"name": name, "obj": name + ".obj", "material": "object", "lightmap_resolution": RES}
        if smooth:
            mesh["smooth"] = True
        meshes.append(mesh)
    el, az = math.radians(45.0), math.radians(30.0)
    z = [math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)]  # towards the sun
    x = list(np.cross([0, 0, 1], z) / np.linalg.norm(np.cross([0, 0, 1], z)))
    y = list(np.cross(z, x))
    sun = [x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 10, 0, 0, 0, 1]
    scene = {
        "version": 1,
        "materials": [{"name": "ground", "albedo": [0.4, 0.36, 0.3]}, {"name": "wall", "albedo": 0.6},
                      {"name": "object", "albedo": [0.7, 0.5, 0.4]}],
        "meshes": meshes,
        "lights": [{"name": "sun", "type": "SUN", "power": 4.0, "angle": 0.00918, "matrix": sun}],
        "world": {"radiance": [0.3, 0.4, 0.6]},
        "settings": settings,
    }
    with open(os.path.join(out, "scene.json"), "w") as f:
        json.dump(scene, f)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True)
    ap.add_argument("--objects", type=int, default=128)
    ap.add_argument("--segments", type=int, default=64, help="rings per sphere (sides: twice that)")
    ap.add_argument("--smooth", action="store_true", help="shade the spheres smooth")
    ap.add_argument("--target", type=float, default=0.05)
    ap.add_argument("--photons", type=int, default=50_000_000, help="photon cap")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--no-bake", action="store_true", help="only write the scene")
    ap.add_argument("--photonlm", default=os.path.join(HERE, "..", "build", "bin", "photonlm"))
    args = ap.parse_args()
    settings = {"photon_count": args.photons, "target_error": args.target, "seed": args.seed}
    build(args.out, args.objects, args.segments, args.smooth, settings)
    if args.no_bake:
        return
    bake_dir = os.path.join(args.out, "bake")
    os.makedirs(bake_dir, exist_ok=True)
    t0 = time.perf_counter()
    subprocess.run([args.photonlm, "bake", os.path.join(args.out, "scene.json"), "-o", bake_dir], check=True,
                   stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    with open(os.path.join(bake_dir, "report.json")) as f:
        rep = json.load(f)
    ph = rep["photons"]
    print("objects %d, wall %.2f s (setup %.2f, direct %.2f, photons %.2f), error estimate %.2f %% (direct %.2f %%), "
          "photons %.1f M, hits %.2f M, hits per photon %.3f"
          % (args.objects, wall, rep["times"]["setup"], rep["times"]["direct"], rep["times"]["trace"],
             100 * rep["stats"]["error_estimate"], 100 * rep["stats"]["error_direct"], ph["emitted"] / 1e6,
             ph["hits"] / 1e6, ph["hits"] / max(ph["emitted"], 1)))


if __name__ == "__main__":
    main()
