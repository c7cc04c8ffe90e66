"""L-system objects: a plant traced as a cyclic scene graph against the same plant flattened.

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so PYTHONPATH=python_bridge \
        /usr/bin/python3 docs/bench_lsystem.py [--depth 15] [--ol-level 4] [--photons 2000000] \
        [--repeats 3] [--skip-forest] [--out docs/images/lsystem_forest.png]
    ... docs/bench_lsystem.py --forest-pair-only [--repeats 3]   # only part 2's 10 trees, graph vs flattened

The tree is the add-on's SYMPODIAL_TREE preset (addon/photonlm_blender/export/lsystem.py) with its
parameters rewritten as integer branch counts (i, j): the preset's A(l, w) / B(l*r1, w*wr) form
gives bit-different lengths for r1*r2 and r2*r1 and so more than 64 states per (module, depth)
beyond depth 13, which the graph (and lsystem_flatten) refuse. The surfaces are the same
(lengths r1^i r2^j, widths 0.1 wr^(i+j)): depth 12 flattens to the preset's matrices within 2e-15.

1. One tree on a 12 x 12 m floor (128 x 128 lightmap), sun at 40 degrees + sky, photons only
   (direct_samples 0): (a) one L-system object (graph, no flattening) and (b) each flattened
   primitive as its own one-leaf CSG solid (Embree BVH over exact cylinders). The variants run
   in turn, --repeats rounds; each round's graph / flattened ratio pairs runs a few seconds apart
   (on a shared machine the load changes between processes), and the table gives the median and
   the range over rounds.
2. A forest of 100 such trees (random position, heading, scale, seed) on a 40 x 40 m floor with a
   256 x 256 lightmap, as 100 L-system objects; the flattened comparison uses 10 trees (100 x 33 k
   one-leaf CSG solids is too heavy for this machine). Error: floor lightmap and tree light
   (Result.lsystem_lookup at points on flattened cylinder sides) against the 100-tree forest baked
   with 8 x the photons and 4 x the direct samples.
Every variant runs in its own process (its peak memory is its own).
"""
import argparse
import ctypes
import json
import resource
import subprocess
import sys
import time

import numpy as np

import photonlm

# SYMPODIAL_TREE (ABOP figure 2.7) as in the add-on, parameters as branch counts.
TREE = (
    "const r1 = 0.9\n"
    "const r2 = 0.7\n"
    "const a1 = 10\n"
    "const a2 = 60\n"
    "const wr = 0.707\n"
    "axiom: A(0, 0)\n"
    "A(i, j) -> !(0.1*wr^(i+j)) F(r1^i*r2^j) [ &(a1) B(i+1, j) ] /(180) [ &(a2) B(i, j+1) ]\n"
    "B(i, j) -> !(0.1*wr^(i+j)) F(r1^i*r2^j) [ +(a1) B(i+1, j) ] [ -(a2) B(i, j+1) ]\n")
STEP, WIDTH = 1.0, 0.1


def tree_placements(n, half):
    rng = np.random.default_rng(7)
    out = []
    for k in range(n):
        x, y = rng.uniform(-half, half, 2)
        h = rng.uniform(0, 2 * np.pi)
        s = rng.uniform(0.8, 1.2)
        m = np.eye(4)
        m[:3, :3] = s * np.array([[np.cos(h), -np.sin(h), 0], [np.sin(h), np.cos(h), 0], [0, 0, 1]])
        m[:3, 3] = (x, y, 0.0)
        out.append((m, 1000 + k))
    return out


def add_lsystem(scene, name, matrix, seed, depth, ol_level, materials, cache_bytes):
    """Scene.add_lsystem, plus plm_lsystem_settings.cache_bytes (the bridge does not expose it)."""
    if not cache_bytes:
        return scene.add_lsystem(name, TREE, depth=depth, seed=seed, matrix=matrix, step=STEP, width=WIDTH,
                                 materials=materials, ol_level=ol_level)
    s, mats = photonlm._lsystem_settings(depth, seed, matrix, STEP, -1, WIDTH, materials, ol_level, 0)
    s.cache_bytes = int(cache_bytes)
    out = ctypes.c_uint32()
    photonlm._check(photonlm._C.plm_scene_add_lsystem(scene._h, name.encode(), TREE.encode(), ctypes.byref(s),
                                                      ctypes.byref(out)))
    del mats
    return out.value


def build(kind, trees, half, res, depth, ol_level, cache_bytes):
    scene = photonlm.Scene()
    grey = scene.add_material(albedo=(0.5, 0.5, 0.5))
    bark = scene.add_material(albedo=(0.45, 0.35, 0.25))
    quad = np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]], np.float32)
    uv = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)
    floor = scene.add_mesh("floor", quad, np.array([[0, 1, 2], [0, 2, 3]], np.uint32), uv,
                           material_ids=np.array([grey, grey], np.uint32), resolution=res)
    ids, prims = [], 0
    for k, (m, seed) in enumerate(trees):
        if kind == "graph":
            ids.append(add_lsystem(scene, "tree %d" % k, m, seed, depth, ol_level, [bark], cache_bytes))
        else:
            shapes, mats, _, trunc = photonlm.lsystem_flatten(TREE, depth=depth, seed=seed, step=STEP,
                                                              width=WIDTH, matrix=m, max_primitives=10 ** 7)
            assert not trunc
            prims += len(shapes)
            for i in range(len(shapes)):
                scene.add_csg("t%d.%d" % (k, i), [dict(shape=photonlm.LSYSTEM_SHAPES[int(shapes[i])],
                                                      matrix=mats[i], material=bark)], 0)
    s, c = np.sin(np.radians(40)), np.cos(np.radians(40))
    sun = np.eye(4, dtype=np.float32)
    sun[:3, :3] = [[1, 0, 0], [0, c, -s], [0, s, c]]
    scene.add_light("SUN", power=3.0, matrix=sun)
    scene.set_world((0.3, 0.35, 0.45))
    return scene, floor, ids, prims


def sample_points(trees, depth, count, tree_count=20):
    """Points on the sides of random flattened cylinders (with outward normals) of up to tree_count trees."""
    rng = np.random.default_rng(11)
    pick = rng.choice(len(trees), min(tree_count, len(trees)), replace=False)
    per = count // len(pick)
    pts, nrm, owner = [], [], []
    for t in pick:
        m, seed = trees[t]
        shapes, mats, _, _ = photonlm.lsystem_flatten(TREE, depth=depth, seed=seed, step=STEP, width=WIDTH, matrix=m,
                                                      max_primitives=10 ** 7)
        cyl = np.flatnonzero(shapes == 2)
        for i in rng.choice(cyl, per):
            phi, z = rng.uniform(0, 2 * np.pi), rng.uniform(-0.9, 0.9)
            M = mats[i]
            p = M[:, :3] @ np.array([np.cos(phi), np.sin(phi), z]) + M[:, 3]
            n = np.linalg.inv(M[:, :3]).T @ np.array([np.cos(phi), np.sin(phi), 0.0])
            pts.append(p)
            nrm.append(n / np.linalg.norm(n))
            owner.append(int(t))
    return np.array(pts), np.array(nrm), np.array(owner)


def run_one(cfg):
    t0 = time.perf_counter()
    trees = tree_placements(cfg["trees"], cfg["spread"]) if cfg["trees"] > 1 else [(np.eye(4), 1000)]
    scene, floor, ids, prims = build(cfg["kind"], trees, cfg["half"], cfg["res"], cfg["depth"], cfg["ol_level"],
                                     cfg.get("cache_bytes", 0))
    t_build = time.perf_counter() - t0
    out = dict(cfg)
    with scene.bake(photons=cfg["photons"], direct_samples=cfg["direct"], seed=cfg["seed"]) as r:
        st = r.stats
        out["map"] = r.lightmap(floor).rgb.mean(axis=2).tolist() if cfg.get("map") else None
        if ids:
            ls = [r.lsystem_stats(i) for i in ids]
            out["ls"] = {k: float(sum(x[k] for x in ls)) for k in ("stubs", "stub_instances", "hits", "classes",
                                                                    "primitives", "cache_hits", "cache_misses",
                                                                    "cache_bytes", "class_bytes", "area", "flux")}
            if cfg.get("lookup"):
                p, n, owner = sample_points(trees, cfg["depth"], cfg["lookup"])
                vals = np.zeros(len(p))
                for t in np.unique(owner):
                    sel = owner == t
                    vals[sel] = r.lsystem_lookup(ids[t], p[sel], n[sel]).mean(axis=1)
                out["lookup_vals"] = vals.tolist()
    scene.close()
    out.update(seconds=time.perf_counter() - t0, seconds_build=t_build, primitives=prims,
               peak_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
               **{k: st[k] for k in ("rays_traced", "seconds_trace", "seconds_setup", "seconds_total",
                                     "seconds_direct", "photons_emitted")})
    return out


def sub(cfg):
    p = subprocess.run([sys.executable, __file__, "--one", json.dumps(cfg)], capture_output=True, text=True)
    if p.returncode:
        sys.stderr.write(p.stderr)
        raise SystemExit("variant %s failed" % cfg)
    return json.loads(p.stdout.strip().splitlines()[-1])


def rrmse(a, b):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.sqrt(np.mean((a - b) ** 2)) / np.mean(b))


def forest_pair(args):
    """The forest's flat-trees trees as L-system objects and flattened, in turn, `repeats` rounds."""
    fb = dict(trees=args.flat_trees, spread=18.0, half=20.0, res=256, depth=args.depth, ol_level=args.ol_level,
              photons=args.forest_photons, direct=args.forest_direct, seed=1, map=False, lookup=0)
    runs = {"graph": [], "flat": []}
    for _ in range(max(1, args.repeats)):
        for kind in runs:
            runs[kind].append(sub(dict(fb, kind=kind)))
    print("\n### Forest pair: %d trees, %.1f M photons, %d direct samples (%d rounds: median, range)\n" % (
        args.flat_trees, args.forest_photons / 1e6, args.forest_direct, max(1, args.repeats)))
    print("| variant | photon rays | photon trace s | photon trace vs flattened | direct s | set-up s | bake s |")
    print("|---|---|---|---|---|---|---|")
    for kind, label in (("graph", "graph"), ("flat", "flattened CSG")):
        rs = runs[kind]
        tr = [r["seconds_trace"] for r in rs]
        ratio = [r["seconds_trace"] / f["seconds_trace"] for r, f in zip(rs, runs["flat"])]

        def med(key):
            v = [r[key] for r in rs]
            return "%.2f (%.2f-%.2f)" % (np.median(v), min(v), max(v))
        print("| %d trees, %s | %d | %.3f (%.3f-%.3f) | %.2fx (%.2f-%.2fx) | %s | %s | %s |" % (
            args.flat_trees, label, rs[0]["rays_traced"], np.median(tr), min(tr), max(tr), np.median(ratio),
            min(ratio), max(ratio), med("seconds_direct"), med("seconds_setup"), med("seconds_total")), flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--depth", type=int, default=15)
    ap.add_argument("--ol-level", type=int, default=4)
    ap.add_argument("--photons", type=int, default=2_000_000)
    ap.add_argument("--forest-photons", type=int, default=500_000)
    ap.add_argument("--forest-direct", type=int, default=4)
    ap.add_argument("--flat-trees", type=int, default=10)
    ap.add_argument("--skip-forest", action="store_true")
    ap.add_argument("--forest-pair-only", action="store_true",
                    help="only the forest's --flat-trees trees, graph against flattened, --repeats rounds "
                         "(no one-tree part, no reference, no 100-tree bakes)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", default=None)
    ap.add_argument("--one", default=None)
    args = ap.parse_args()
    if args.one:
        print(json.dumps(run_one(json.loads(args.one))))
        return
    d, lvl = args.depth, args.ol_level
    n = len(photonlm.lsystem_flatten(TREE, depth=d, step=STEP, width=WIDTH, max_primitives=10 ** 7)[0])
    print("tree: SYMPODIAL_TREE depth %d = %d primitives, ol_level %d" % (d, n, lvl))

    if args.forest_pair_only:
        forest_pair(args)
        return

    # 1. one tree, photons only: the variants in turn, `repeats` rounds.
    base = dict(trees=1, spread=0, half=6.0, res=128, depth=d, ol_level=lvl, photons=args.photons, direct=0, seed=1)
    variants = [("graph (L-system object), cache 64 MiB", dict(base, kind="graph")),
                ("flattened (%d one-leaf CSG solids)" % n, dict(base, kind="flat")),
                ("graph, cache 1 MiB", dict(base, kind="graph", cache_bytes=1 << 20)),
                ("graph, cache 64 KiB", dict(base, kind="graph", cache_bytes=64 << 10))]
    runs = {label: [] for label, _ in variants}
    for _ in range(max(1, args.repeats)):
        for label, cfg in variants:
            runs[label].append(sub(cfg))
    flat_label = variants[1][0]

    def per_ray(r):
        return r["seconds_trace"] / r["rays_traced"]

    print("\n### One tree, %.0f M photons, photons only (%d rounds: median, range)\n" % (
        args.photons / 1e6, max(1, args.repeats)))
    print("| variant | rays traced | trace s | M rays/s | trace time per ray vs flattened | set-up s | "
          "peak memory MB | cache hit rate | peak cache MB | stubs |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for label, _ in variants:
        rs = runs[label]
        ratios = [per_ray(r) / per_ray(f) for r, f in zip(rs, runs[flat_label])]
        trace = [r["seconds_trace"] for r in rs]
        r = rs[0]
        ls = r.get("ls")
        hit = ("%.1f %%" % (100 * ls["cache_hits"] / max(1, ls["cache_hits"] + ls["cache_misses"]))) if ls else "-"
        print("| %s | %d | %.2f (%.2f-%.2f) | %.2f | %.2fx (%.2f-%.2fx) | %.2f | %.0f | %s | %s | %s |" % (
            label, r["rays_traced"], np.median(trace), min(trace), max(trace),
            r["rays_traced"] / np.median(trace) / 1e6, np.median(ratios), min(ratios), max(ratios),
            np.median([x["seconds_setup"] for x in rs]), max(x["peak_mb"] for x in rs), hit,
            ("%.1f" % (ls["cache_bytes"] / 2 ** 20)) if ls else "-",
            ("%d of %d" % (ls["stubs"], ls["stub_instances"])) if ls else "-"), flush=True)
    g = runs[variants[0][0]][0]["ls"]
    print("\ngraph: %d node classes, %.2f MB of classes; flux on the tree %.4g W" % (
        g["classes"], g["class_bytes"] / 2 ** 20, g["flux"]))
    if args.skip_forest:
        return

    # 2. the forest.
    fb = dict(trees=100, spread=18.0, half=20.0, res=256, depth=d, ol_level=lvl, photons=args.forest_photons,
              direct=args.forest_direct, seed=1, map=True, lookup=2000)
    ref = sub(dict(fb, kind="graph", photons=8 * args.forest_photons, direct=4 * args.forest_direct, seed=99))
    print("\nreference: 100 L-system trees, %.0f M photons, %d direct samples: %.1f s" % (
        ref["photons"] / 1e6, ref["direct"], ref["seconds"]))
    g100 = sub(dict(fb, kind="graph"))
    g100b = sub(dict(fb, kind="graph", seed=2))
    gk = sub(dict(fb, kind="graph", trees=args.flat_trees, lookup=0))
    fk = sub(dict(fb, kind="flat", trees=args.flat_trees, lookup=0))
    ref_map, ref_look = np.array(ref["map"]), np.array(ref["lookup_vals"])
    print("\n### Forest, %.1f M photons, %d direct samples\n" % (args.forest_photons / 1e6, args.forest_direct))
    print("| variant | primitives | bake s (engine) | set-up s | photon trace s | direct s | M photon rays/s | peak memory MB | "
          "floor error vs reference | tree light error vs reference |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for label, r in (("100 trees, graph (seed 1)", g100), ("100 trees, graph (seed 2)", g100b),
                     ("%d trees, graph" % args.flat_trees, gk), ("%d trees, flattened CSG" % args.flat_trees, fk)):
        prims = int(r["ls"]["primitives"]) if r.get("ls") else r["primitives"]
        fe = ("%.2f %%" % (100 * rrmse(r["map"], ref_map))) if r["trees"] == 100 else "-"
        te = ("%.2f %%" % (100 * rrmse(r["lookup_vals"], ref_look))) if r.get("lookup_vals") else "-"
        print("| %s | %d | %.2f | %.2f | %.2f | %.2f | %.2f | %.0f | %s | %s |" % (
            label, prims, r["seconds_total"], r["seconds_setup"], r["seconds_trace"], r["seconds_direct"],
            r["rays_traced"] / max(1e-9, r["seconds_trace"]) / 1e6, r["peak_mb"], fe, te),
            flush=True)
    print("\n%d trees: floor lightmap graph vs flattened (same photons, seed 1): %.2f %% relative RMS difference; "
          "two 100-tree graph bakes (seeds 1, 2): %.2f %%" % (
              args.flat_trees, 100 * rrmse(gk["map"], fk["map"]), 100 * rrmse(g100["map"], g100b["map"])))
    print("tree light: mean lookup %.4g (1x) vs %.4g (reference); seed 1 vs seed 2: %.2f %%; reference stubs "
          "with hits %d of %d" % (np.mean(g100["lookup_vals"]), ref_look.mean(),
                                   100 * rrmse(g100["lookup_vals"], g100b["lookup_vals"]), ref["ls"]["stubs"],
                                   ref["ls"]["stub_instances"]))
    if args.out:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(1, 3, figsize=(13, 4.2))
        vmax = np.percentile(ref_map, 99)
        ax[0].imshow(ref_map, origin="lower", cmap="gray", vmax=vmax)
        ax[0].set_title("floor, reference (100 L-system trees)")
        ax[1].imshow(np.array(g100["map"]), origin="lower", cmap="gray", vmax=vmax)
        ax[1].set_title("floor, %.0f M photons" % (args.forest_photons / 1e6))
        ax[2].loglog(np.maximum(ref_look, 1e-5), np.maximum(g100["lookup_vals"], 1e-5), ".", ms=2)
        ax[2].plot([1e-5, 1], [1e-5, 1], "k-", lw=0.5)
        ax[2].set_xlabel("reference lookup")
        ax[2].set_ylabel("1x lookup")
        ax[2].set_title("tree light at %d bark points" % len(ref_look))
        fig.tight_layout()
        fig.savefig(args.out, dpi=90)
        print("plot:", args.out)


if __name__ == "__main__":
    main()
