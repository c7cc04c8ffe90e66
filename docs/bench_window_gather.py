"""The final gather's blend in a room lit through an open window: does it keep the light?

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so PYTHONPATH=python_bridge \\
        /usr/bin/python3 docs/bench_window_gather.py [--seeds 24] [--photons 8000000] [--reference 64000000]

Scene: a room 4 x 4 x 2.5 m of one-sided quads facing inward (floor albedo 0.5, walls and ceiling
0.6), its wall at x = 2 with an open window of 1.5 x 1 m (no pane), a sun of 3 W/m^2 35 degrees up
shining in through it, nothing outside. The walls and the ceiling see no sun: their light is all
bounce light, which the final gather and the photons each estimate without bias.

Prints, per surface, the mean of its covered texels from default bakes (the final gather blended
with the photons; --photons photons, 64 direct samples) over --seeds seeds, relative to a reference
of photons alone (2 seeds of --reference photons, no pooling, no gather: max_bounces 63), with the
standard error of that mean over the seeds; for both texel values (AREA: whole-texel means, which
the reference is; CYCLES: the central square, which on these surfaces, without direct light, differs
from the whole-texel mean only by the bounce light's curvature); and the same for photons alone at
--photons (pooled as by default, no gather), one of the two estimates the blend weighs.
"""
import argparse
import time

import numpy as np

import photonlm
from bench_caustics import TRI, UV, quad

SURFACES = (("floor", (-2, -2, 0), (4, 0, 0), (0, 4, 0), 32),
            ("ceiling", (-2, 2, 2.5), (4, 0, 0), (0, -4, 0), 16),
            ("wall -x", (-2, -2, 0), (0, 4, 0), (0, 0, 2.5), 16),
            ("wall -y", (2, -2, 0), (-4, 0, 0), (0, 0, 2.5), 16),
            ("wall +y", (-2, 2, 0), (4, 0, 0), (0, 0, 2.5), 16),
            ("window wall below", (2, 2, 0), (0, -4, 0), (0, 0, 0.8), 8),
            ("window wall above", (2, 2, 1.8), (0, -4, 0), (0, 0, 0.7), 8),
            ("window wall left", (2, 2, 0.8), (0, -1.25, 0), (0, 0, 1.0), 8),
            ("window wall right", (2, -0.75, 0.8), (0, -1.25, 0), (0, 0, 1.0), 8))


def build(scene):
    wall = scene.add_material(0.6, name="wall")
    floor = scene.add_material(0.5, name="floor")
    maps = []
    for name, o, eu, ev, res in SURFACES:
        m = floor if name == "floor" else wall
        maps.append(scene.add_mesh(name, quad(o, eu, ev), TRI, UV, material_ids=[m, m], resolution=res))
    elev = np.radians(35.0)
    z = np.array([np.cos(elev), 0.0, np.sin(elev)])  # towards the sun
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = x, np.cross(z, x), z
    scene.add_light("SUN", power=3.0, angle=0.0, matrix=m)
    return maps


def surface_means(seed, **settings):
    with photonlm.Scene() as scene:
        maps = build(scene)
        with scene.bake(seed=seed, direct_samples=64, **settings) as r:
            means = []
            for i in maps:
                lm = r.lightmap(i)
                covered = lm.coverage.reshape(-1) > 0
                means.append(lm.rgb.reshape(-1, 3).mean(axis=1)[covered].mean())
    return np.array(means)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=24)
    ap.add_argument("--photons", type=int, default=8_000_000)
    ap.add_argument("--reference", type=int, default=64_000_000)
    args = ap.parse_args()
    t0 = time.perf_counter()
    ref = np.mean([surface_means(100 + s, photons=args.reference, max_bounces=63, filter_radius=0,
                                 texel_value="AREA") for s in range(2)], axis=0)
    print("reference: photons alone, 2 x %d photons, %.1f s" % (args.reference, time.perf_counter() - t0))
    rows = {}
    for value in ("AREA", "CYCLES"):
        t0 = time.perf_counter()
        runs = np.array([surface_means(1 + s, photons=args.photons, texel_value=value) for s in range(args.seeds)])
        rows[value] = (runs.mean(axis=0) / ref, runs.std(axis=0) / np.sqrt(args.seeds) / ref)
        print("%s: %d bakes of %d photons, %.2f s each" % (value, args.seeds, args.photons,
                                                           (time.perf_counter() - t0) / args.seeds))
    runs = np.array([surface_means(1 + s, photons=args.photons, max_bounces=63, texel_value="AREA")
                     for s in range(args.seeds)])
    rows["photons alone"] = (runs.mean(axis=0) / ref, runs.std(axis=0) / np.sqrt(args.seeds) / ref)
    print("%-18s %16s %16s %16s" % ("surface", "AREA", "CYCLES", "photons alone"))
    for k, (name, *_) in enumerate(SURFACES):
        print("%-18s" % name + "".join("   %.4f +- %.4f" % (rows[v][0][k], rows[v][1][k]) for v in rows))


if __name__ == "__main__":
    main()
