"""What live previews cost (Scene.bake(preview=...), plm_bake_with_preview), on the furnace box.

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so PYTHONPATH=python_bridge:docs \
        /usr/bin/python3 docs/bench_live_preview.py

For each lightmap size: the same bake (fixed photon count and seed) without previews, with a
preview every 3 s (the add-on's default) and every 0.5 s, each preview copying the whole lightmap
into numpy as the add-on does. Prints the bake's wall time, the previews taken
and the mean seconds per preview, the final texel error against the exact answer E / (1 - rho) and
that of the last preview, and whether the final lightmap equals the one without previews.
"""
import time

import numpy as np

from bench_furnace import furnace_scene

RHO = 0.5
PHOTONS = 30_000_000


def bake(res, interval):
    scene, mesh = furnace_scene(RHO, res)
    seconds = []
    last = []

    def preview(p):
        t0 = time.perf_counter()
        rgb = p.lightmap(mesh)
        seconds.append(time.perf_counter() - t0)
        last[:] = [rgb]

    t0 = time.perf_counter()
    kwargs = dict(preview=preview, preview_interval=interval) if interval else {}
    with scene.bake(photons=PHOTONS, seed=1, direct_samples=16, **kwargs) as result:
        wall = time.perf_counter() - t0
        lm = result.lightmap(mesh)
    scene.close()
    return wall, seconds, lm, (last[0] if last else None)


def rel_rmse(rgb, coverage):
    exact = 1.0 / (1.0 - RHO)
    value = rgb.mean(axis=2)[coverage > 0.999]
    return float(np.sqrt(np.mean((value - exact) ** 2)) / exact)


def main():
    print("%-10s %-18s %8s %9s %12s %10s %12s %s" % ("lightmap", "previews", "bake s", "previews",
                                                      "s/preview", "error", "last prev.", "same result"))
    for res in (64, 256):
        reference = None
        for label, interval in (("off", 0.0), ("every 3 s", 3.0), ("every 0.5 s", 0.5)):
            wall, seconds, lm, last = bake(res, interval)
            if reference is None:
                reference = lm
            same = all(np.array_equal(a, b) for a, b in zip(lm, reference))
            print("%-10s %-18s %8.2f %9d %12s %9.2f%% %12s %s"
                  % ("%dx%d" % (3 * res, 2 * res), label, wall, len(seconds),
                     "%.4f" % np.mean(seconds) if seconds else "-", 100 * rel_rmse(lm.rgb, lm.coverage),
                     "%.2f%%" % (100 * rel_rmse(last, lm.coverage)) if last is not None else "-", same))


if __name__ == "__main__":
    main()
