"""Owen-scrambled Sobol points against pseudo-random numbers, at equal sample counts.

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so PYTHONPATH=python_bridge:python_bridge/tests \
        /usr/bin/python3 docs/bench_sampler.py [--seeds 6]

For each case and sampler, the texel RMS error against an exact (or converged) answer is
averaged over independent seeds, with the error the engine reported next to it:
  area light  square area light 0.5 m over a black plane, direct pass only; exact answer in
              closed form (rectangle form factor), averaged over each texel's central half
  sky + box   uniform sky over a black plane with a 1 m box on it (ambient occlusion), direct
              pass only; reference: 16384 Sobol samples per texel
  furnace     closed box, emission 1, albedo 0.5: exact 1 / (1 - 0.5) everywhere; photons only
              (the photon sampler alone) and the default two passes
Samplers: RANDOM (pseudo-random everywhere), DEFAULT (Sobol for the direct pass, pseudo-random
photons), SOBOL (Sobol photon paths too).
"""
import argparse
import math
import sys
import time

import numpy as np

import photonlm
from scenes import plane, texel_average, translation, QUAD_TRIANGLES, QUAD_UV, box_faces

sys.path.insert(0, __file__.rsplit("/", 1)[0])
from bench_furnace import furnace_scene  # noqa: E402


def area_light_case(samples, sampler, seed, res=32):
    power, a, h = 400.0, 0.5, 1.0
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.0)
        pos, tri, uv = plane(2.0)
        mesh = scene.add_mesh("floor", pos, tri, uv, resolution=res)
        scene.add_light("AREA_RECT", power=power, size=a, matrix=translation(0, 0, h))
        t0 = time.perf_counter()
        with scene.bake(photons=1000, max_bounces=0, seed=seed, direct_samples=samples, sampler=sampler) as r:
            seconds = time.perf_counter() - t0
            lm = r.lightmap(mesh)
    radiance = power / (4 * a * a)

    def irradiance(px, py):  # a rectangle's irradiance / pi at points (px, py) of the plane, arrays
        def f(x, y):
            return (x / np.hypot(x, h) * np.arctan(y / np.hypot(x, h))
                    + y / np.hypot(y, h) * np.arctan(x / np.hypot(y, h)))
        x0, x1, y0, y1 = -a / 2 - px, a / 2 - px, -a / 2 - py, a / 2 - py
        return radiance / 2 * (f(x1, y1) - f(x0, y1) - f(x1, y0) + f(x0, y0)) / math.pi
    # The texel value: the average over the texel's central half (texel_value CYCLES), points
    # folded into the quad's triangle that owns the texel centre as Cycles folds them.
    truth = texel_average(irradiance, -2.0, 2.0, -2.0, 2.0, res, res, window=0.5, fold_quad=(-2.0, 2.0, -2.0, 2.0))
    return lm.rgb.mean(axis=2), truth, lm.error, seconds


def sky_box_scene(scene):
    scene.add_material(albedo=0.0)
    pos, tri, uv = plane(4.0)
    mesh = scene.add_mesh("floor", pos, tri, uv, resolution=32)
    for i, quad in enumerate(box_faces()):  # a unit cube standing on the floor's centre
        q = np.asarray(quad, np.float32) - np.array([0.5, 0.5, 0.0], np.float32)
        scene.add_mesh("box%d" % i, q, QUAD_TRIANGLES, QUAD_UV)
    scene.set_world((0.5, 0.5, 0.5))
    return mesh


_SKY_REF = {}


def sky_case(samples, sampler, seed):
    if "ref" not in _SKY_REF:
        with photonlm.Scene() as scene:
            mesh = sky_box_scene(scene)
            with scene.bake(photons=1000, max_bounces=0, seed=12345, direct_samples=16384) as r:
                _SKY_REF["ref"] = r.lightmap(mesh).rgb.mean(axis=2)
    with photonlm.Scene() as scene:
        mesh = sky_box_scene(scene)
        t0 = time.perf_counter()
        with scene.bake(photons=1000, max_bounces=0, seed=seed, direct_samples=samples, sampler=sampler) as r:
            seconds = time.perf_counter() - t0
            lm = r.lightmap(mesh)
    return lm.rgb.mean(axis=2), _SKY_REF["ref"], lm.error, seconds


def furnace_case(photons, sampler, seed, direct_samples):
    scene, mesh = furnace_scene(0.5)
    t0 = time.perf_counter()
    with scene.bake(photons=photons, seed=seed, direct_samples=direct_samples, filter_radius=0,
                    sampler=sampler) as r:
        seconds = time.perf_counter() - t0
        lm = r.lightmap(mesh)
    scene.close()
    full = lm.coverage > 0.999
    return lm.rgb.mean(axis=2)[full], np.full(full.sum(), 2.0), lm.error[full], seconds


def measure(case, setting, sampler, seeds):
    errs, reps, secs = [], [], []
    for seed in range(seeds):
        value, truth, error, seconds = case(setting, sampler, seed)
        mask = truth > 0
        mean = truth[mask].mean()
        errs.append(np.sqrt(np.mean((value[mask] - truth[mask]) ** 2)) / mean)
        reps.append(np.sqrt(np.mean(error[mask] ** 2)) / mean)
        secs.append(seconds)
    return float(np.sqrt(np.mean(np.square(errs)))), float(np.sqrt(np.mean(np.square(reps)))), float(np.median(secs))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=6)
    args = ap.parse_args()
    cases = [
        ("area light, direct samples", area_light_case, (16, 64, 256), ("RANDOM", "DEFAULT")),
        ("sky + box, direct samples", sky_case, (16, 64, 256), ("RANDOM", "DEFAULT")),
        ("furnace photons only, photons", lambda n, s, seed: furnace_case(n, s, seed, 0),
         (250_000, 1_000_000), ("RANDOM", "SOBOL")),
        ("furnace two passes, photons", lambda n, s, seed: furnace_case(n, s, seed, 64),
         (250_000, 1_000_000), ("RANDOM", "DEFAULT", "SOBOL")),
    ]
    print("| case | setting | sampler | texel RMSE | reported | seconds | variance vs RANDOM |")
    print("|---|---|---|---|---|---|---|")
    for label, case, settings, samplers in cases:
        for setting in settings:
            base = None
            for sampler in samplers:
                err, rep, sec = measure(case, setting, sampler, args.seeds)
                base = base or err
                print("| %s | %s | %s | %.3f %% | %.3f %% | %.3f | %.2g |"
                      % (label, setting, sampler, 100 * err, 100 * rep, sec, (err / base) ** 2), flush=True)


if __name__ == "__main__":
    main()
