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


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--groups", default="0,1,2,4,8")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--target", type=float, default=0.02)
    ap.add_argument("--case", type=int)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    if args.case is not None:
        return one_case(args.case, args.seed, args.target)

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


if __name__ == "__main__":
    main()
