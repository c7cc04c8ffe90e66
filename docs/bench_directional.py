"""Directional lightmaps (SH L1): what they cost in time and memory, and how close their direction is
to a converged one at each target.

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so PYTHONPATH=python_bridge:python_bridge/tests:docs \
        /usr/bin/python3 docs/bench_directional.py [--targets 0.05,0.02,0.01] [--seeds 2]

The room of docs/bench_light_groups.py --dim without groups: 4 x 4 x 2.5 m, five 48 x 48 lightmapped
faces, a sun and a sky through a window and two lamps. Each case (a target, plain or directional, a
seed) bakes in a process of its own, which reports its peak resident memory (ru_maxrss) and the
engine's time; medians over seeds, the ratio directional / plain per seed first.

Speed against error: each directional bake's moments D (the SH's L1 as world vectors, photonlm.h
"Directional lightmaps") against a converged directional bake (target 0.2 %): relative RMSE =
sqrt(mean |D - D_ref|^2) / mean(V_ref) over every covered texel and channel, beside the lightmap's
own relative RMSE (V against V_ref).
"""
import argparse
import json
import resource
import subprocess
import sys

import numpy as np

import photonlm
from bench_light_groups import dim_room

EVAL0, EVAL1 = 0.28209479177387814, 0.32573500793527993


def bake(target, seed, directional):
    """Per face the value V (h, w, 3), the moments D (h, w, 3 channels, 3 axes) or None, coverage; and stats."""
    with photonlm.Scene() as scene:
        faces = dim_room(scene, groups=False)
        with scene.bake(target_error=target, seed=seed, directional=directional, photons=0) as r:
            out = []
            for f in faces:
                lm = r.lightmap(f)
                d = None
                if directional:
                    sh = r.lightmap_sh(f)
                    d = np.stack([EVAL1 * sh[3], EVAL1 * sh[1], EVAL1 * sh[2]], axis=-1)
                out.append((lm.rgb, d, lm.coverage > 0))
            return out, r.stats


def one_case(target, seed, directional):
    _, s = bake(target, seed, directional)
    print(json.dumps({"total": s["seconds_total"], "error": s["error_estimate"], "photons": s["photons_emitted"],
                      "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
                      "estimate_mb": s["memory_estimate"] / 2 ** 20}))


def run_case(target, seed, directional):
    p = subprocess.run([sys.executable, __file__, "--case", str(target), "--seed", str(seed)] +
                       (["--directional"] if directional else []), capture_output=True, text=True, check=True)
    return json.loads(p.stdout.strip().splitlines()[-1])


def errors(maps, ref):
    dv, dd, v = [], [], []
    for (rgb, d, c), (rrgb, rd, _) in zip(maps, ref):
        dv.append((rgb - rrgb)[c].ravel())
        dd.append(np.linalg.norm(d - rd, axis=-1)[c].ravel())
        v.append(rrgb[c].ravel())
    mean = np.mean(np.concatenate(v))
    return (float(np.sqrt(np.mean(np.concatenate(dv) ** 2)) / mean),
            float(np.sqrt(np.mean(np.concatenate(dd) ** 2)) / mean))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--targets", default="0.05,0.02,0.01")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--reference", type=float, default=0.002)
    ap.add_argument("--case", type=float)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--directional", action="store_true")
    a = ap.parse_args()
    if a.case is not None:
        return one_case(a.case, a.seed, a.directional)
    targets = [float(t) for t in a.targets.split(",")]
    print("| target | plain s | directional s | time ratio | plain MB | directional MB | estimate MB (plain / dir.) |")
    print("|---|---|---|---|---|---|---|")
    for t in targets:
        rows = [(run_case(t, s, False), run_case(t, s, True)) for s in range(1, a.seeds + 1)]
        med = lambda f: float(np.median([f(p, d) for p, d in rows]))  # noqa: E731
        print("| %.1f %% | %.2f | %.2f | %.3f | %.0f | %.0f | %.0f / %.0f |" % (
            100 * t, med(lambda p, d: p["total"]), med(lambda p, d: d["total"]),
            med(lambda p, d: d["total"] / p["total"]), med(lambda p, d: p["peak_mb"]), med(lambda p, d: d["peak_mb"]),
            med(lambda p, d: p["estimate_mb"]), med(lambda p, d: d["estimate_mb"])))
    sys.stdout.flush()
    ref, rs = bake(a.reference, 99, True)
    print("\nreference: %.2f %% estimated, %.0f s\n" % (100 * rs["error_estimate"], rs["seconds_total"]))
    print("| target | s | lightmap rel. RMSE | moments rel. RMSE |")
    print("|---|---|---|---|")
    for t in targets:
        maps, s = bake(t, 1, True)
        ev, ed = errors(maps, ref)
        print("| %.1f %% | %.2f | %.2f %% | %.2f %% |" % (100 * t, s["seconds_total"], 100 * ev, 100 * ed))


if __name__ == "__main__":
    main()
