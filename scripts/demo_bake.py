"""Demo: bake the Cornell box with PhotonLM inside Blender and check it against Cycles.

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so \
        blender -b --factory-startup --python scripts/demo_bake.py -- --out out/demo

Builds the Cornell box of blend_tests/scenes.py, bakes it through bpy.ops.photonlm.bake()
(the add-on's operator), prints photons, bake time and photons/s, and compares each object's
coverage-weighted mean lightmap value (its average irradiance / pi) with the converged Cycles
reference of this Blender: scripts/cornell_reference_<major>.<minor>.json where there is one
(make_cornell_reference.py --out writes it), else scripts/cornell_reference.json (Blender 3.4's
Cycles; a Blender from 4.0 bakes its area light 4 / pi brighter, so that comparison says so). Writes the EXR lightmaps and cornell.png (a
Cycles render of the baked lightmaps through the preview materials) to --out.
"""
import argparse
import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "blend_tests"))
os.environ.setdefault("PHOTONLM_SOURCE_DIR", ROOT)
import scenes  # noqa: E402

import bpy  # noqa: E402


def own_reference_path():
    return os.path.join(HERE, "cornell_reference_%d.%d.json" % tuple(bpy.app.version[:2]))


def reference_path():
    """This Blender's own reference if there is one, else Blender 3.4's."""
    own = own_reference_path()
    return own if os.path.exists(own) else os.path.join(HERE, "cornell_reference.json")


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="demo_bake.py")
    ap.add_argument("--out", default="out/demo", help="folder for the EXR lightmaps and cornell.png")
    ap.add_argument("--photons", type=int, default=20_000_000)
    ap.add_argument("--resolution", type=int, default=64)
    ap.add_argument("--render-size", type=int, default=512)
    ap.add_argument("--render-samples", type=int, default=16)
    args = ap.parse_args(argv)
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    t_start = time.perf_counter()

    scenes.setup_paths()
    from photonlm_blender import bridge
    lib = getattr(bridge.get(), "library_path", "")
    print("photonlm %s (%s)" % (bridge.get().version(), lib() if callable(lib) else lib))
    scenes.clear_scene()
    scenes.cornell_box(resolution=args.resolution)
    scenes.cornell_camera()
    scene = bpy.context.scene
    scene.photonlm.output_dir = out + os.sep
    scene.photonlm.preview = True

    last = scenes.photonlm_bake(args.photons, 1024, seed=0)
    st = last["stats"]
    print("baked %d lightmaps (%dx%d): %s photons in %.2f s = %.2f M photons/s (scene export %.3f s, %d warnings)"
          % (len(last["objects"]), args.resolution, args.resolution, "{:,}".format(st["photons_emitted"]),
             st["seconds_total"], st["photons_per_second"] / 1e6, st["seconds_export"], st["warning_count"]))
    for w in sorted({t for level, t in last["reports"] if level == 'WARNING'}):
        print("  warning:", w)

    with open(reference_path()) as f:
        ref = json.load(f)
    if (int(ref["blender"].split(".")[0]) >= 4) != (bpy.app.version[0] >= 4):
        print("note: the reference is Blender %s's Cycles, whose area lights have other units than Blender %s's "
              "(4.0 made them 4 / pi brighter): the errors below measure that, not the bake; write this "
              "Blender's reference with scripts/make_cornell_reference.py -- --out %s"
              % (ref["blender"], bpy.app.version_string, own_reference_path()))
    print("error against the converged Cycles reference (%s samples, Blender %s): per object, coverage-weighted "
          "mean of irradiance/pi, relative error of the RGB mean" % (ref["cycles"]["samples"], ref["blender"]))
    errs = []
    for name in scenes.CORNELL_OBJECTS:
        o = last["objects"][name]
        ours = scenes.coverage_weighted_mean(o["rgb"], o["coverage"])
        want = ref["mean_irradiance_over_pi"][name]
        err = abs(float(ours.mean()) / (sum(want) / 3.0) - 1.0)
        errs.append(err)
        print("  %-9s ours (%.4f %.4f %.4f)  cycles (%.4f %.4f %.4f)  error %.2f %%"
              % ((name,) + tuple(float(c) for c in ours) + tuple(want) + (100 * err,)))
    print("mean error over objects %.2f %%, max %.2f %%" % (100 * sum(errs) / len(errs), 100 * max(errs)))

    # Render the baked scene through the preview materials (emission = albedo x lightmap).
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = args.render_samples
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 0
    scene.render.resolution_x = scene.render.resolution_y = args.render_size
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = 'PNG'
    scene.render.filepath = os.path.join(out, "cornell.png")
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    print("rendered %s in %.1f s" % (scene.render.filepath, time.perf_counter() - t0))
    print("lightmaps: %s" % ", ".join(sorted(os.path.basename(o["path"]) for o in last["objects"].values())))
    print("demo finished in %.1f s" % (time.perf_counter() - t_start))


main()
