"""Exact CSG against tessellated meshes: a riveted plate.

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so PYTHONPATH=python_bridge \
        /usr/bin/python3 docs/bench_csg.py [--rivets 2500] [--out docs/images/csg_rivets.png]

A 4 x 4 m plate (an exact CSG box whose top face is carried by a quad with a 128 x 128
lightmap) with N hemispherical rivets (r = 2 cm) on a grid, lit by a sun at 40 degrees and a
sky. Variants: rivets as exact CSG spheres (one solid each: thousands of primitives in one
Embree BVH), or as UV-sphere meshes of 6 x 3 to 48 x 24 segments. Each variant runs in its own
process (its peak memory is its own) at the same settings; error = relative RMSE of the plate's
lightmap against a converged bake of the exact scene (16 x the direct samples, 8 x the photons).
"""
import argparse
import json
import os
import resource
import subprocess
import sys
import time

import numpy as np

import photonlm

PLATE, RIVET_R = 4.0, 0.02


def rivet_centres(n):
    k = int(np.ceil(np.sqrt(n)))
    xs = (np.arange(k) + 0.5) / k * (PLATE * 0.9) - PLATE * 0.45
    pts = np.array([(x, y) for y in xs for x in xs])[:n]
    return pts


def uv_sphere(segments, rings):
    """Unit UV sphere: positions (V, 3), triangles (T, 3)."""
    pos, tris = [], []
    for j in range(rings + 1):
        th = np.pi * j / rings
        for i in range(segments):
            ph = 2 * np.pi * i / segments
            pos.append((np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)))
    for j in range(rings):
        for i in range(segments):
            a, b = j * segments + i, j * segments + (i + 1) % segments
            c, d = a + segments, b + segments
            if j > 0:
                tris.append((a, b, d))
            if j < rings - 1:
                tris.append((a, d, c))
    return np.array(pos, np.float32), np.array(tris, np.uint32)


def build(variant, n):
    scene = photonlm.Scene()
    grey = scene.add_material(albedo=(0.6, 0.6, 0.6))
    metal = scene.add_material(albedo=(0.7, 0.65, 0.5))
    plate = np.diag([PLATE / 2, PLATE / 2, 0.05, 1.0])
    plate[2, 3] = -0.05  # top face at z = 0
    solid = scene.add_csg("plate", [dict(shape="BOX", matrix=plate, material=grey)], 0)
    h = PLATE / 2
    quad = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], np.float32)
    uv = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)
    top = scene.add_mesh("plate top", quad, np.array([[0, 1, 2], [0, 2, 3]], np.uint32), uv,
                         material_ids=np.array([grey, grey], np.uint32), resolution=128)
    scene.set_csg_carrier(solid, top)
    centres = rivet_centres(n)
    if variant == "csg":
        for k, (x, y) in enumerate(centres):
            m = np.diag([RIVET_R, RIVET_R, RIVET_R, 1.0])
            m[:3, 3] = (x, y, 0.0)
            scene.add_csg("rivet %d" % k, [dict(shape="SPHERE", matrix=m, material=metal)], 0)
    else:
        seg = int(variant.split("x")[0])
        p, t = uv_sphere(seg, seg // 2)
        allp = np.concatenate([p * RIVET_R + np.array([x, y, 0.0], np.float32) for x, y in centres])
        allt = np.concatenate([t + k * len(p) for k in range(len(centres))])
        scene.add_mesh("rivets", allp, allt, None, material_ids=np.full(len(allt), metal, np.uint32))
    s, c = np.sin(np.radians(40)), np.cos(np.radians(40))
    sun = np.eye(4, dtype=np.float32)
    sun[:3, :3] = [[1, 0, 0], [0, c, -s], [0, s, c]]  # tilt the sun 40 degrees about x
    scene.add_light("SUN", power=3.0, matrix=sun)
    scene.set_world((0.3, 0.35, 0.45))
    return scene, top


def run_one(variant, n, photons, direct, seed):
    t0 = time.perf_counter()
    scene, top = build(variant, n)
    t_build = time.perf_counter() - t0
    with scene.bake(photons=photons, direct_samples=direct, seed=seed) as r:
        lm = r.lightmap(top).rgb.mean(axis=2)
        st = r.stats
    scene.close()
    return dict(variant=variant, rivets=n, seconds=time.perf_counter() - t0, seconds_build=t_build,
                seconds_engine=st["seconds_total"], seconds_setup=st["seconds_setup"],
                peak_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
                reported=st["error_estimate"], map=lm.tolist())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rivets", type=int, default=2500)
    ap.add_argument("--out", default=None)
    ap.add_argument("--one", nargs=5, metavar=("VARIANT", "N", "PHOTONS", "DIRECT", "SEED"))
    args = ap.parse_args()
    if args.one:
        v, n, p, d, s = args.one
        print(json.dumps(run_one(v, int(n), int(p), int(d), int(s))))
        return

    def sub(*a):
        out = subprocess.run([sys.executable, __file__, "--one", *map(str, a)], check=True,
                             capture_output=True, text=True).stdout
        return json.loads(out.strip().splitlines()[-1])
    n = args.rivets
    ref = sub("csg", n, 8_000_000, 1024, 99)
    ref_map = np.array(ref["map"])
    print("reference: exact CSG, 8 M photons, 1024 direct samples: %.1f s" % ref["seconds"])
    print("| rivets as | primitives / triangles | seconds (engine) | set-up s | peak memory MB | "
          "plate error vs reference | reported |")
    print("|---|---|---|---|---|---|---|")
    rows = []
    for variant in ("csg", "6x3", "12x6", "24x12", "48x24"):
        r = sub(variant, n, 1_000_000, 64, 1)
        err = float(np.sqrt(np.mean((np.array(r["map"]) - ref_map) ** 2)) / ref_map.mean())
        seg = 0 if variant == "csg" else int(variant.split("x")[0])
        size = ("%d spheres" % n) if variant == "csg" else ("%d triangles" % (n * seg * (seg // 2 - 1) * 2))
        rows.append((variant, r["seconds_engine"], err))
        print("| %s | %s | %.2f | %.2f | %.0f | %.2f %% | %.2f %% |" % (
            "exact CSG" if variant == "csg" else "UV spheres %s" % variant, size, r["seconds_engine"],
            r["seconds_setup"], r["peak_mb"], 100 * err, 100 * r["reported"]), flush=True)
    if args.out:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(1, 2, figsize=(9, 4))
        ax[0].imshow(ref_map, origin="lower", cmap="gray")
        ax[0].set_title("plate lightmap (reference, exact rivets)")
        for v, t, e in rows:
            ax[1].loglog(t, 100 * e, "o", label=v)
        ax[1].set_xlabel("engine seconds")
        ax[1].set_ylabel("plate error vs reference (%)")
        ax[1].legend()
        ax[1].grid(True, which="both", alpha=0.3)
        fig.tight_layout()
        fig.savefig(args.out, dpi=100)
        print("plot:", args.out)


if __name__ == "__main__":
    main()
