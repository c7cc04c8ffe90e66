"""Memory per triangle and per lightmap texel of a bake, measured, against the engine's own estimate.

    PHOTONLM_LIBRARY=$PWD/build/lib/libphotonlm.so PYTHONPATH=python_bridge \
        /usr/bin/python3 docs/bench_memory.py [--out /tmp/bench_memory.json]

Each configuration bakes in a fresh process (through the Python bridge) and reports its peak
resident memory (getrusage maxrss) less the process's resident memory just before the scene is
made (Python, numpy, the engine library), and the engine's estimate (stats memory_estimate, the
number the memory check compares with the memory free). Two series:
- triangles: a lightmapped grid of T triangles (a 64 x 64 lightmap whose UVs follow the grid),
  T = 0.25 M to 2 M;
- texels: one quad with an n x n lightmap wholly covered, n = 256 to 2048.
Both lit by a sun, baked with 200 k photons and 1 direct sample per texel (memory does not grow
with either). A least-squares line through each series gives bytes per triangle and per texel.
"""
import argparse
import json
import os
import resource
import subprocess
import sys

import numpy as np


def rss_now():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def grid(n):
    """An n x n grid of quads (2 n^2 triangles) on the unit square, UVs = positions."""
    xs = np.linspace(0.0, 1.0, n + 1, dtype=np.float32)
    gx, gy = np.meshgrid(xs, xs, indexing="xy")
    pos = np.stack([gx.ravel() * 10.0, gy.ravel() * 10.0, np.zeros(gx.size, np.float32)], axis=1)
    i = np.arange(n, dtype=np.uint32)
    a = (i[None, :] + (n + 1) * i[:, None]).ravel()
    b, c, d = a + 1, a + n + 2, a + n + 1
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    uv = (pos[:, :2] / 10.0)[tris]
    return pos, tris, uv


def one(kind, size):
    import photonlm
    base = rss_now()
    scene = photonlm.Scene()
    scene.add_material((0.6, 0.6, 0.6))
    if kind == "triangles":
        n = int(round(np.sqrt(size / 2.0)))
        pos, tris, uv = grid(n)
        resolution = 64
    else:
        pos, tris, uv = grid(1)
        resolution = size
    scene.add_mesh("m", pos, tris, lightmap_uv=uv, resolution=resolution)
    scene.add_light('SUN', power=3.0, matrix=[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 5], [0, 0, 0, 1]])
    result = scene.bake(photons=200_000, target_error=0.0, direct_samples=1, seed=1)
    stats = result.stats
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    print(json.dumps(dict(kind=kind, triangles=int(len(tris)), texels=int(resolution * resolution),
                          peak=int(peak - base), estimate=float(stats["memory_estimate"]),
                          seconds=float(stats["seconds_total"]))))


def fit(xs, ys):
    slope, intercept = np.polyfit(np.asarray(xs, float), np.asarray(ys, float), 1)
    return float(slope), float(intercept)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="/tmp/bench_memory.json")
    ap.add_argument("--one", nargs=2, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.one:
        one(args.one[0], int(args.one[1]))
        return
    plan = [("triangles", t) for t in (250_000, 500_000, 1_000_000, 2_000_000)] + \
           [("texels", n) for n in (256, 512, 1024, 2048)]
    rows = []
    for kind, size in plan:
        out = subprocess.run([sys.executable, os.path.abspath(__file__), "--one", kind, str(size)],
                             capture_output=True, text=True, check=True).stdout
        row = json.loads(out.strip().splitlines()[-1])
        rows.append(row)
        print("%-9s %9d triangles %9d texels: peak %7.1f MB, estimate %7.1f MB (%.1f s)"
              % (kind, row["triangles"], row["texels"], row["peak"] / 1e6, row["estimate"] / 1e6, row["seconds"]),
              flush=True)
    summary = {}
    for kind, key in (("triangles", "triangles"), ("texels", "texels")):
        sel = [r for r in rows if r["kind"] == kind]
        summary[kind] = dict(measured=fit([r[key] for r in sel], [r["peak"] for r in sel]),
                             estimated=fit([r[key] for r in sel], [r["estimate"] for r in sel]))
        print("%s: measured %.0f bytes each (+ %.0f MB), estimated %.0f bytes each (+ %.0f MB)"
              % (kind, summary[kind]["measured"][0], summary[kind]["measured"][1] / 1e6,
                 summary[kind]["estimated"][0], summary[kind]["estimated"][1] / 1e6))
    with open(args.out, "w") as f:
        json.dump(dict(rows=rows, fits=summary), f, indent=1)


if __name__ == "__main__":
    main()
