"""Bake a .blend file's lightmaps without the UI (run by scripts/bake_blend.sh):

    blender -b FILE.blend --python-exit-code 1 --python scripts/bake_blend.py -- \
        [-o DIR] [--target-error E] [--time-budget S] [--photons N] [--seed N] [--save] [--pack]
        [--export-scene SCENE.json]

Enables the PhotonLM add-on (from this source tree when run from it, else the installed one),
bakes the file's current scene synchronously with its PhotonLM settings (options override them),
printing progress and the reached error, writes one EXR per object (to -o DIR, default the
scene's output folder, //lightmaps/ next to the .blend), and with --save saves the .blend with
the lightmap images linked to those files (--pack: packed into the .blend). --export-scene
writes the scene file instead of baking. Exits 0 on success, 1 with a message on any failure.
"""
import argparse
import os
import sys
import time

import bpy


def fail(message):
    print("bake_blend: error: %s" % message, file=sys.stderr, flush=True)
    sys.exit(1)


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="bake_blend", description="Bake a .blend file's PhotonLM lightmaps")
    p.add_argument("-o", "--out", help="folder for the lightmap EXRs (default: the scene's output folder)")
    p.add_argument("--target-error", type=float, help="relative RMS error to reach, e.g. 0.02 (0 = none)")
    p.add_argument("--time-budget", type=float, help="seconds for the bake (0 = no limit)")
    p.add_argument("--photons", type=int, help="photon cap (exact count without a target or budget)")
    p.add_argument("--seed", type=int, help="random seed")
    p.add_argument("--save", action="store_true", help="save the .blend with the lightmap images")
    p.add_argument("--pack", action="store_true", help="with --save: pack the images into the .blend")
    p.add_argument("--export-scene", metavar="SCENE.json", help="write a scene file instead of baking")
    try:
        return p.parse_args(argv)
    except SystemExit as e:
        sys.exit(1 if e.code else 0)


def enable_addon():
    """The source tree's add-on and bridge if this script is in one, else the installed add-on."""
    src = os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if os.path.isfile(os.path.join(src, "addon", "photonlm_blender", "__init__.py")):
        for sub in ("addon", "python_bridge"):
            if os.path.join(src, sub) not in sys.path:
                sys.path.insert(0, os.path.join(src, sub))
        import photonlm_blender
        if not hasattr(bpy.types.Scene, "photonlm"):
            photonlm_blender.register()
        return photonlm_blender
    import addon_utils
    mod = addon_utils.enable("photonlm_blender", default_set=False, persistent=True)
    if mod is None:
        fail("the PhotonLM add-on (photonlm_blender) is not installed and this script is not in a source tree")
    return mod


def main():
    args = parse_args()
    if not bpy.data.is_saved:
        fail("no .blend file given (usage: blender -b FILE.blend --python scripts/bake_blend.py -- [options])")
    enable_addon()
    from photonlm_blender.bake import job as bake
    from photonlm_blender.export import scene as export
    from photonlm_blender.bake import scene_file as scene_file_export
    scene = bpy.context.scene
    s = scene.photonlm
    for attr, value in (("target_error", args.target_error), ("time_budget", args.time_budget),
                        ("photons", args.photons), ("seed", args.seed)):
        if value is not None:
            try:
                setattr(s, attr, value)
            except (TypeError, ValueError) as e:
                fail("--%s %r: %s" % (attr.replace("_", "-"), value, e))
            if getattr(s, attr) != value and not abs(getattr(s, attr) - value) < 1e-6:
                fail("--%s %r is out of range (clamped to %r)" % (attr.replace("_", "-"), value, getattr(s, attr)))
    if args.out:
        s.output_dir = os.path.abspath(args.out)
    if args.pack:
        s.pack_lightmaps = True
    if args.export_scene:
        reports = export.Reports()
        try:
            path, meta = scene_file_export.export_scene_file(bpy.context, args.export_scene, reports)
        except Exception as e:  # noqa: BLE001
            fail("export failed: %s" % e)
        print("bake_blend: wrote %s (%d lightmapped objects)" % (path, len(meta["objects"])), flush=True)
        return
    print("bake_blend: %s, scene '%s': target error %g, time budget %g s, photons %d, seed %d"
          % (bpy.data.filepath, scene.name, s.target_error, s.time_budget, s.photons, s.seed), flush=True)
    try:
        job = bake.BakeJob(bpy.context)
    except (bake.BakeError, RuntimeError) as e:
        fail(str(e))
    except Exception as e:  # noqa: BLE001
        fail("could not export the scene: %s" % e)
    state = {"stage": None, "step": -1, "t0": time.perf_counter()}

    def progress(fraction, stage):
        step = int(10 * fraction)
        if stage != state["stage"] or step != state["step"]:
            state["stage"], state["step"] = stage, step
            print("bake_blend: %-10s %3d%%  (%.1f s)" % (stage, round(100 * fraction),
                                                       time.perf_counter() - state["t0"]), flush=True)
        return True

    job.run(progress)
    if job.cancelled or job.error:
        job.abort(bpy.context)
        for level, text in job.reports.items:
            print("bake_blend: %s: %s" % (level.lower(), text), flush=True)
        fail(job.error or "the bake was cancelled")
    try:
        last = job.finish(bpy.context)
    except Exception as e:  # noqa: BLE001
        job.abort(bpy.context)
        fail("could not store the lightmaps: %s" % (getattr(e, "message", None) or e))
    st = last["stats"]
    for name, o in sorted(last["objects"].items()):
        print("bake_blend: %-24s %4d x %-4d -> %s" % (name, o["size"][0], o["size"][1], o["path"]), flush=True)
    for name, o in sorted(last["ols"].items()):
        print("bake_blend: OL %-21s -> %s" % (name, o["path"]), flush=True)
    print("bake_blend: %d lightmaps, %s photons in %.2f s, error estimate %.4f (median %.4f, p95 %.4f), "
          "%d warnings" % (len(last["objects"]), "{:,}".format(int(st["photons_emitted"])), st["seconds_total"],
                           st["error_estimate"], st["error_median"], st["error_p95"], st["warning_count"]),
          flush=True)
    if args.save:
        try:
            bpy.ops.wm.save_mainfile()
        except RuntimeError as e:
            fail("could not save %s: %s" % (bpy.data.filepath, e))
        print("bake_blend: saved %s (lightmap images %s)" % (bpy.data.filepath,
                                                             "packed" if args.pack else "linked"), flush=True)


main()
