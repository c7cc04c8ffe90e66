"""One-off: the converged Cycles reference for scripts/demo_bake.py (writes cornell_reference.json).

    blender -b --factory-startup --python scripts/make_cornell_reference.py [-- --samples 4096]

Builds the Cornell box of blend_tests/scenes.py, bakes it with Cycles (DIFFUSE, DIRECT +
INDIRECT, no COLOR = irradiance / pi; 32 bounces, no clamping, box filter) and stores, per
object, the coverage-weighted mean RGB of its lightmap. With a uniform texel density inside
each object this is the area-weighted mean of irradiance / pi over the object's surface, so
it does not depend on the lightmap layout or resolution.
"""
import argparse
import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "blend_tests"))
import scenes  # noqa: E402

import bpy  # noqa: E402


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser()
    ap.add_argument("--samples", type=int, default=4096)
    ap.add_argument("--resolution", type=int, default=32)
    ap.add_argument("--out", default=os.path.join(HERE, "cornell_reference.json"))
    args = ap.parse_args(argv)
    scenes.setup_paths()
    scenes.clear_scene()
    objs = scenes.cornell_box(resolution=args.resolution)
    meshes = [objs[n] for n in scenes.CORNELL_OBJECTS]
    t0 = time.perf_counter()
    ref, seconds = scenes.cycles_bake(meshes, args.resolution, {'DIRECT', 'INDIRECT'}, args.samples, bounces=32)
    means = {}
    for name in scenes.CORNELL_OBJECTS:
        cov = scenes.layout_coverage(objs[name], args.resolution)
        means[name] = [round(float(c), 6) for c in scenes.coverage_weighted_mean(ref[name], cov)]
    data = {
        "description": "Per-object area-weighted mean of irradiance/pi (linear RGB) in the Cornell box of "
                       "blend_tests/scenes.py cornell_box(), converged Cycles DIFFUSE bake "
                       "(DIRECT+INDIRECT, no COLOR)",
        "blender": bpy.app.version_string,
        "cycles": {"samples": args.samples, "max_bounces": 32, "diffuse_bounces": 32, "clamp": 0,
                   "resolution": args.resolution, "seconds": round(seconds, 1), "filter": "BOX 1 px"},
        "scene": {"light": "AREA SQUARE 0.5 m, 40 W, at (0, 0, 1.98) facing -z",
                  "albedo": scenes.CORNELL_ALBEDO},
        "mean_irradiance_over_pi": means,
    }
    with open(args.out, "w") as f:
        json.dump(data, f, indent=2, sort_keys=True)
        f.write("\n")
    print("wrote %s (Cycles %.1f s, total %.1f s)" % (args.out, seconds, time.perf_counter() - t0))
    for k, v in means.items():
        print("  %-9s %s" % (k, v))


main()
