"""Many point lights over a black plane: the direct pass's light choice, speed against error.

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so PYTHONPATH=python_bridge:python_bridge/tests \
        /usr/bin/python3 docs/bench_many_lights.py [--lights 12,48,100,300] [--seeds 3]

N point lights at random positions (x, y in [-9, 9] m, height 0.5-2.5 m) and powers (100-1000 W)
over a 20 x 20 m black plane (64 x 64 texels), direct light only, at 4 / 16 / 64 samples per
texel. Error: relative RMSE = sqrt(mean((value - truth)^2)) / mean(truth) against the closed form
(each texel's central half, as Cycles bakes it), as in bench_vs_cycles.py, and the RMS of the
per-texel relative error (value - truth) / truth, which the dark texels between lights dominate;
both root-mean-square over seeds. Reported: the engine's error_estimate (the first measure's
estimate). Seconds: the engine's direct-pass time and the whole bake, medians over seeds.

--sun-shade: the lamps (1 m up, 100 W) share the plane with a sun at the zenith (10 W/m^2, a
sharp disc) that a black roof 3 m up hides from the half x < 0; the per-texel relative RMS error
is given for the shaded and the lit half, at 16 / 64 / 256 samples.
"""
import argparse
import math
import time

import numpy as np

import photonlm
from scenes import plane, texel_average, translation


def case(count, samples, seed, res=64):
    rng = np.random.default_rng(1000 + count)
    xs, ys = rng.uniform(-9, 9, count), rng.uniform(-9, 9, count)
    hs, powers = rng.uniform(0.5, 2.5, count), rng.uniform(100, 1000, count)
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.0)
        pos, tri, uv = plane(10.0)
        mesh = scene.add_mesh("floor", pos, tri, uv, resolution=res)
        for x, y, h, p in zip(xs, ys, hs, powers):
            scene.add_light("POINT", power=float(p), radius=0.0, matrix=translation(x, y, h))
        t0 = time.perf_counter()
        with scene.bake(photons=1000, max_bounces=0, seed=seed, direct_samples=samples) as r:
            wall = time.perf_counter() - t0
            lm = r.lightmap(mesh)
            stats = r.stats

    def irradiance_over_pi(x, y):
        e = np.zeros_like(x)
        for lx, ly, h, p in zip(xs, ys, hs, powers):
            d2 = (x - lx) ** 2 + (y - ly) ** 2 + h * h
            e += p / (4 * math.pi) * h / d2 ** 1.5
        return e / math.pi
    truth = texel_average(irradiance_over_pi, -10, 10, -10, 10, res, res, window=0.5,
                          fold_quad=(-10.0, 10.0, -10.0, 10.0))
    diff = lm.rgb.mean(axis=2) - truth
    rmse = float(np.sqrt(np.mean(diff ** 2)) / np.mean(truth))
    texel = float(np.sqrt(np.mean((diff / truth) ** 2)))
    return rmse, stats["error_estimate"], stats["seconds_direct"], wall, texel


def sun_shade_case(count, samples, seed, res=64):
    rng = np.random.default_rng(2000 + count)
    xs, ys = rng.uniform(-9, 9, count), rng.uniform(-9, 9, count)
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.0)
        pos, tri, uv = plane(10.0)
        mesh = scene.add_mesh("floor", pos, tri, uv, resolution=res)
        roof = np.array([[-10.5, -10.5, 3], [0, -10.5, 3], [0, 10.5, 3], [-10.5, 10.5, 3]], np.float32)
        scene.add_mesh("roof", roof, tri)
        for x, y in zip(xs, ys):
            scene.add_light("POINT", power=100.0, radius=0.0, matrix=translation(x, y, 1.0))
        scene.add_light("SUN", power=10.0, angle=0.0)
        with scene.bake(photons=1000, max_bounces=0, seed=seed, direct_samples=samples) as r:
            lm = r.lightmap(mesh)
            stats = r.stats

    def irradiance_over_pi(x, y):
        e = np.where(x > 0, 10.0, 0.0)
        for lx, ly in zip(xs, ys):
            d2 = (x - lx) ** 2 + (y - ly) ** 2 + 1.0
            e = e + 100.0 / (4 * math.pi) / d2 ** 1.5
        return e / math.pi
    truth = texel_average(irradiance_over_pi, -10, 10, -10, 10, res, res, window=0.5,
                          fold_quad=(-10.0, 10.0, -10.0, 10.0))
    rel = (lm.rgb.mean(axis=2) - truth) / truth
    half = res // 2  # columns of x < 0
    shade = float(np.sqrt(np.mean(rel[:, :half] ** 2)))
    lit = float(np.sqrt(np.mean(rel[:, half:] ** 2)))
    return shade, lit, stats["error_estimate"], stats["seconds_direct"]


def sun_shade(args):
    print("| lamps | samples | shaded half | lit half | reported | direct s |")
    print("|---|---|---|---|---|---|")
    for count in [int(c) for c in args.lights.split(",")]:
        for samples in (16, 64, 256):
            runs = [sun_shade_case(count, samples, seed) for seed in range(1, args.seeds + 1)]
            rms = [math.sqrt(np.mean([r[i] ** 2 for r in runs])) for i in range(3)]
            print("| %d | %d | %.2f %% | %.3f %% | %.2f %% | %.4f |" % (
                count, samples, 100 * rms[0], 100 * rms[1], 100 * rms[2], np.median([r[3] for r in runs])))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--lights", default="12,48,100,300")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--sun-shade", action="store_true", help="lamps and a sun that a roof hides from half the plane")
    args = ap.parse_args()
    if args.sun_shade:
        sun_shade(args)
        return
    print("| lights | samples | relative RMSE | reported | per-texel relative RMS | direct s | bake s |")
    print("|---|---|---|---|---|---|---|")
    for count in [int(c) for c in args.lights.split(",")]:
        for samples in (4, 16, 64):
            runs = [case(count, samples, seed) for seed in range(1, args.seeds + 1)]
            rmse = math.sqrt(np.mean([r[0] ** 2 for r in runs]))
            reported = math.sqrt(np.mean([r[1] ** 2 for r in runs]))
            texel = math.sqrt(np.mean([r[4] ** 2 for r in runs]))
            print("| %d | %d | %.2f %% | %.2f %% | %.2f %% | %.4f | %.3f |" % (
                count, samples, 100 * rmse, 100 * reported, 100 * texel, np.median([r[2] for r in runs]),
                np.median([r[3] for r in runs])))


if __name__ == "__main__":
    main()
