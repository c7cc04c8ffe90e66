"""Direct light through glass: a room lit by the sun through a glass window pane (a slab: two
parallel faces 2 cm apart, IOR 1.5), baked two ways at equal photon counts:

  pass     shadow rays and gather rays pass the pane with its Fresnel weight (the engine's
           design): the sun patch on the floor is direct light, computed per texel;
  block    the pane stops shadow rays and photons carry all light through it (the pane given a
           second, zero-weight lobe, which makes it opaque to straight rays and changes nothing
           else): the sun patch is a caustic, estimated from photons.

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so PYTHONPATH=python_bridge \\
        /usr/bin/python3 docs/bench_caustics.py [--reference 64000000] [--max 16000000] [--texel-value AREA]

Prints, per design and photon count, the bake's time and the RMS texel error of all lightmaps
against a reference (the pass design with --reference photons and 256 direct samples), relative
to the mean texel value, and the error of the sun patch's texels alone. With --texel-value
CYCLES (the engine's default) the pass design's direct light is the texel's central square's, as
Cycles bakes it, which photons (a whole-texel mean) cannot give: the block design then keeps a bias
at the patch's edges; AREA compares both on whole-texel means.
"""
import argparse
import time

import numpy as np

import photonlm

TRI = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
UV = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)


def quad(o, eu, ev):
    """Corners o, o + eu, o + eu + ev, o + ev: front side along eu x ev."""
    o, eu, ev = (np.asarray(v, np.float32) for v in (o, eu, ev))
    return np.array([o, o + eu, o + eu + ev, o + ev], np.float32)


def build(scene, design):
    wall = scene.add_material(0.6, name="wall")
    floor = scene.add_material(0.5, name="floor")
    glass = scene.add_material(0.0, name="glass")
    scene.add_material_lobe(glass, "glass", 1.0, ior=1.5)
    if design == "block":
        scene.add_material_lobe(glass, "glossy", 1.0, weight=0.0)
    maps = []

    def mesh(name, corners, material, res):
        maps.append(scene.add_mesh(name, corners, TRI, UV, material_ids=[material, material], resolution=res))

    # A room 4 x 4 x 2.5 m, faces inward; the wall at x = 2 has a 1 x 1 m window.
    mesh("floor", quad((-2, -2, 0), (4, 0, 0), (0, 4, 0)), floor, 32)
    mesh("ceiling", quad((-2, 2, 2.5), (4, 0, 0), (0, -4, 0)), wall, 16)
    mesh("wall -x", quad((-2, -2, 0), (0, 4, 0), (0, 0, 2.5)), wall, 16)
    mesh("wall -y", quad((2, -2, 0), (-4, 0, 0), (0, 0, 2.5)), wall, 16)
    mesh("wall +y", quad((-2, 2, 0), (4, 0, 0), (0, 0, 2.5)), wall, 16)
    for name, o, eu, ev in (("below", (2, 2, 0), (0, -4, 0), (0, 0, 0.8)),
                            ("above", (2, 2, 1.8), (0, -4, 0), (0, 0, 0.7)),
                            ("left", (2, 2, 0.8), (0, -1.5, 0), (0, 0, 1.0)),
                            ("right", (2, -0.5, 0.8), (0, -1.5, 0), (0, 0, 1.0))):
        mesh("window wall " + name, quad(o, eu, ev), wall, 8)
    # The pane: outer face at x = 2.01 facing out, inner face at x = 1.99 facing in.
    scene.add_mesh("pane out", quad((2.01, -0.5, 0.8), (0, 1, 0), (0, 0, 1)), TRI, material_ids=[glass, glass])
    scene.add_mesh("pane in", quad((1.99, 0.5, 0.8), (0, -1, 0), (0, 0, 1)), TRI, material_ids=[glass, glass])
    # The sun 35 degrees above the horizon, shining in through the window.
    elev = np.radians(35.0)
    d = np.array([-np.cos(elev), 0.0, -np.sin(elev)])
    z = -d
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2] = x, y, z
    scene.add_light("SUN", power=3.0, angle=0.0, matrix=m)
    return maps


def bake(design, photons, direct_samples, seed, texel_value):
    with photonlm.Scene() as scene:
        maps = build(scene, design)
        t0 = time.perf_counter()
        with scene.bake(photons=photons, direct_samples=direct_samples, seed=seed,
                        texel_value=texel_value) as result:
            wall = time.perf_counter() - t0
            values = [result.lightmap(i).rgb.reshape(-1, 3).mean(axis=1) for i in maps]
            covered = [result.lightmap(i).coverage.reshape(-1) > 0 for i in maps]
    return wall, np.concatenate(values), np.concatenate(covered)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--reference", type=int, default=64_000_000)
    ap.add_argument("--max", type=int, default=16_000_000)
    ap.add_argument("--texel-value", default="AREA", choices=("AREA", "CYCLES"))
    args = ap.parse_args()
    t, ref, cov = bake("pass", args.reference, 256, 99, args.texel_value)
    print("reference: pass design, %d photons, 256 direct samples, texel value %s, %.1f s"
          % (args.reference, args.texel_value, t))
    patch = cov & (ref > 2.0 * np.median(ref[cov]))  # the sun patch (and its bright surroundings)
    mean = ref[cov].mean()
    print("%-6s %10s %8s %10s %10s" % ("design", "photons", "s", "error %", "patch %"))
    n = 1_000_000
    while n <= args.max:
        for design in ("pass", "block"):
            t, v, _ = bake(design, n, 64, 7, args.texel_value)
            err = np.sqrt(np.mean((v[cov] - ref[cov]) ** 2)) / mean
            perr = np.sqrt(np.mean((v[patch] - ref[patch]) ** 2)) / ref[patch].mean()
            print("%-6s %10d %8.2f %10.2f %10.2f" % (design, n, t, 100 * err, 100 * perr))
        n *= 4


if __name__ == "__main__":
    main()
