"""Light groups: what the layers cost in time and memory, and how close a layer is to its group's own bake.

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so PYTHONPATH=python_bridge:python_bridge/tests \
        /usr/bin/python3 docs/bench_light_groups.py [--groups 0,1,2,4,8] [--seeds 3] [--target 0.02]

A 6 x 4 x 3 m room (six inward faces of grey 0.6, 24 texels per metre: 96 x 72 to 144 x 96 texels),
lit by 8 point lamps under the ceiling (100-400 W), baked to a target error. The lamps go round
robin into G light groups (0: no groups). Each case runs in a process of its own, which reports
its peak resident memory (ru_maxrss) and the engine's times; medians over seeds.

Then speed against error for two groups: the two layers of one bake against two bakes, one per
group's lamps, at the same target; each measured against a converged bake of that group's lamps
(target 0.3 %): relative RMSE = sqrt(mean((value - ref)^2)) / mean(ref) over every covered texel.

Last, a dim group (--dim): a 4 x 4 x 2.5 m room with a window, a sun and a sky through it in group
"day" beside two lamps in "night" giving about 30x its light, baked to 1 %; the day layer against a
converged bake of the sun and sky alone (0.4 %), and a bake of them alone at 1 %.
"""
import argparse
import json
import math
import resource
import subprocess
import sys

import numpy as np

import photonlm
from scenes import box_faces

SIZE = (6.0, 4.0, 3.0)
RES_PER_M = 24
LAMPS = [(x, y, 2.6, p) for (x, y), p in zip([(-2, -1), (0, -1), (2, -1), (-2, 1), (0, 1), (2, 1), (-1, 0), (1, 0)],
                                            [100, 250, 400, 150, 300, 200, 350, 120])]


def build(scene, groups, lamps=None):
    """The room; lamps (indices into LAMPS, all by default) in `groups` groups round robin."""
    scene.add_material(albedo=0.6)
    meshes = []
    for k, corners in enumerate(box_faces()):
        pos = (corners * np.array(SIZE, np.float32) - np.array([SIZE[0] / 2, SIZE[1] / 2, 0], np.float32))
        tri = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
        uv = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)
        du, dv = np.linalg.norm(pos[1] - pos[0]), np.linalg.norm(pos[3] - pos[0])
        meshes.append(scene.add_mesh("face%d" % k, pos.astype(np.float32), tri, uv,
                                     resolution=(int(du * RES_PER_M), int(dv * RES_PER_M))))
    ids = [scene.add_light_group("g%d" % g) for g in range(groups)]
    for i in (range(len(LAMPS)) if lamps is None else lamps):
        x, y, z, p = LAMPS[i]
        m = np.eye(4, dtype=np.float32)
        m[:3, 3] = (x, y, z)
        light = scene.add_light("POINT", power=float(p), radius=0.05, matrix=m)
        if groups:
            scene.set_light_group(ids[i % groups], light=light)
    return meshes


def one_case(groups, seed, target):
    """Runs in a child process: prints the bake's figures as JSON."""
    with photonlm.Scene() as scene:
        build(scene, groups)
        with scene.bake(target_error=target, seed=seed) as r:
            s = r.stats
            out = {"total": s["seconds_total"], "direct": s["seconds_direct"], "trace": s["seconds_trace"],
                   "error": s["error_estimate"], "photons": s["photons_emitted"], "layers": len(r.layers),
                   "layer_errors": [r.layer_error(l) for l in range(len(r.layers))]}
    out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(json.dumps(out))


def run_case(groups, seed, target):
    p = subprocess.run([sys.executable, __file__, "--case", str(groups), "--seed", str(seed), "--target", str(target)],
                       capture_output=True, text=True, check=True)
    return json.loads(p.stdout.strip().splitlines()[-1])


def maps(lamps, target, seed, groups=0):
    """Per face, the baked RGB and coverage (per layer with groups: a list per layer), and the bake's seconds."""
    with photonlm.Scene() as scene:
        meshes = build(scene, groups, lamps)
        with scene.bake(target_error=target, seed=seed) as r:
            covered = [r.lightmap(m).coverage > 0 for m in meshes]
            if not groups:
                return [(r.lightmap(m).rgb, c) for m, c in zip(meshes, covered)], r.stats["seconds_total"]
            return ([[(r.lightmap_layer(m, l)[0], c) for m, c in zip(meshes, covered)] for l in range(groups)],
                    r.stats["seconds_total"])


def rmse(maps_, refs):
    diff = np.concatenate([(a[0] - b[0])[a[1]].ravel() for a, b in zip(maps_, refs)])
    ref = np.concatenate([b[0][b[1]].ravel() for b in refs])
    return float(np.sqrt(np.mean(diff ** 2)) / np.mean(ref))


def dim_room(scene, day=True, night=True, groups=True):
    """The room of --dim: five 48 x 48 lightmapped faces and a window wall; returns the faces' ids."""
    tri = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    uv = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)
    mats = [scene.add_material(albedo=a) for a in (0.7, (0.6, 0.5, 0.4), (0.3, 0.6, 0.3))]

    def quad(name, c, res, m):
        return scene.add_mesh(name, np.array(c, np.float32), tri, uv, material_ids=np.array([m, m], np.uint32),
                              resolution=res)
    faces = [quad("floor", [(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], 48, mats[1]),
             quad("ceiling", [(-2, -2, 2.5), (-2, 2, 2.5), (2, 2, 2.5), (2, -2, 2.5)], 48, mats[0]),
             quad("back", [(2, 2, 0), (2, -2, 0), (2, -2, 2.5), (2, 2, 2.5)], 48, mats[0]),
             quad("left", [(-2, 2, 0), (2, 2, 0), (2, 2, 2.5), (-2, 2, 2.5)], 48, mats[2]),
             quad("right", [(2, -2, 0), (-2, -2, 0), (-2, -2, 2.5), (2, -2, 2.5)], 48, mats[0])]
    for k, (y0, y1, z0, z1) in enumerate([(-2, 2, 0, 0.8), (-2, 2, 1.8, 2.5), (-2, -0.8, 0.8, 1.8),
                                          (0.8, 2, 0.8, 1.8)]):
        quad("window%d" % k, [(-2, y0, z0), (-2, y1, z0), (-2, y1, z1), (-2, y0, z1)], 12, mats[0])
    ids = [scene.add_light_group("day"), scene.add_light_group("night")] if groups else None
    if day:
        d = np.array([math.cos(math.radians(40)), 0.0, -math.sin(math.radians(40))])  # the sun's travel
        z = -d
        x = np.cross([0.0, 1.0, 0.0], z)
        x /= np.linalg.norm(x)
        m = np.eye(4, dtype=np.float32)
        m[:3, 0], m[:3, 1], m[:3, 2] = x, np.cross(z, x), z
        sun = scene.add_light("SUN", power=8.0, matrix=m)
        scene.set_world((0.9, 1.2, 2.0))
        if groups:
            scene.set_light_group(ids[0], light=sun)
            scene.set_light_group(ids[0], world=True)
    if night:
        for (x, y, z), kind, power in (((0.5, 1.0, 2.0), "POINT", 240.0), ((0.8, -1.0, 2.45), "AREA_RECT", 160.0)):
            m = np.eye(4, dtype=np.float32)
            m[:3, 3] = (x, y, z)
            lamp = scene.add_light(kind, power=power, radius=0.1, size=0.6, size_y=0.6, matrix=m)
            if groups:
                scene.set_light_group(ids[1], light=lamp)
    return faces


def dim_maps(target, seed, **kw):
    """The --dim room's faces (the day layer with groups) and the bake's seconds and error figures."""
    with photonlm.Scene() as scene:
        faces = dim_room(scene, **kw)
        with scene.bake(target_error=target, seed=seed) as r:
            covered = [r.lightmap(m).coverage > 0 for m in faces]
            rgb = [r.lightmap_layer(m, 0)[0] if r.layers else r.lightmap(m).rgb for m in faces]
            error = r.layer_error(0) if r.layers else r.stats["error_estimate"]
            return list(zip(rgb, covered)), r.stats["seconds_total"], r.stats["error_estimate"], error


def dim_group(seeds):
    ref = dim_maps(0.004, 99, night=False, groups=False)[0]
    print()
    print("| seed | whole error | day layer RMSE | its estimate | bake s | day alone RMSE | day alone s |")
    print("|---|---|---|---|---|---|---|")
    for seed in range(1, seeds + 1):
        layer, t, whole, reported = dim_maps(0.01, seed)
        alone, t_alone, _, _ = dim_maps(0.01, seed, night=False, groups=False)
        print("| %d | %.2f %% | %.1f %% | %.1f %% | %.2f | %.2f %% | %.1f |" % (
            seed, 100 * whole, 100 * rmse(layer, ref), 100 * reported, t, 100 * rmse(alone, ref), t_alone))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--groups", default="0,1,2,4,8")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--target", type=float, default=0.02)
    ap.add_argument("--dim", action="store_true", help="only the dim group's room")
    ap.add_argument("--case", type=int)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    if args.case is not None:
        return one_case(args.case, args.seed, args.target)
    if args.dim:
        return dim_group(args.seeds)

    print("| groups | layers | bake s | direct s | photons s | peak MB | error estimate | layers' errors |")
    print("|---|---|---|---|---|---|---|---|")
    for g in [int(x) for x in args.groups.split(",")]:
        runs = [run_case(g, seed, args.target) for seed in range(1, args.seeds + 1)]
        med = {k: float(np.median([r[k] for r in runs])) for k in ("total", "direct", "trace", "peak_mb", "error")}
        layer_errors = np.median([r["layer_errors"] for r in runs], axis=0) if g else []
        print("| %d | %d | %.2f | %.2f | %.2f | %.0f | %.2f %% | %s |" % (
            g, runs[0]["layers"], med["total"], med["direct"], med["trace"], med["peak_mb"], 100 * med["error"],
            ", ".join("%.1f %%" % (100 * e) for e in layer_errors) or "-"))

    # Two groups: lamps 0, 2, 4, 6 and 1, 3, 5, 7.
    halves = [[0, 2, 4, 6], [1, 3, 5, 7]]
    refs = [maps(h, 0.003, 99)[0] for h in halves]
    print()
    print("| seed | layer 0 RMSE | layer 1 RMSE | one bake s | lamps 0 alone RMSE | lamps 1 alone RMSE | two bakes s |")
    print("|---|---|---|---|---|---|---|")
    for seed in range(1, args.seeds + 1):
        (l0, l1), t = maps(None, args.target, seed, groups=2)
        a0, t0 = maps(halves[0], args.target, seed)
        a1, t1 = maps(halves[1], args.target, seed)
        print("| %d | %.2f %% | %.2f %% | %.2f | %.2f %% | %.2f %% | %.2f |" % (
            seed, 100 * rmse(l0, refs[0]), 100 * rmse(l1, refs[1]), t, 100 * rmse(a0, refs[0]),
            100 * rmse(a1, refs[1]), t0 + t1))
    dim_group(args.seeds)


if __name__ == "__main__":
    main()
