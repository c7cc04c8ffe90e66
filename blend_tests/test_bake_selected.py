"""Bake Selected: only the selected objects get new lightmaps; every other visible object still
blocks and reflects light, and its lightmap stays as it was.

Expected, on the Cornell box (a full bake first, then the floor and the short box selected and
baked again with another seed):
- the unselected objects' images and EXR files are unchanged, bit for bit;
- the selected objects' lightmaps are new (another seed) and agree with the full bake within
  noise: mean relative difference below 3 x the combined error estimates, about 0.06 (the light
  the walls and the tall box reflect onto them is still there: baked with those objects hidden,
  the floor differs by 0.46 and the short box by 0.31);
- with nothing selected, Bake Selected refuses and names why, and changes nothing.
"""
import hashlib
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

SELECTED = ("floor", "short_box")


def digest(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def pixels(name):
    image = bpy.data.images[name]
    px = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(px)
    return px


def main():
    checks = scenes.Checks("bake_selected")
    scenes.setup_paths()
    scenes.clear_scene()
    scenes.cornell_box(resolution=16)
    bpy.context.scene.photonlm.output_dir = scenes.out_dir("bake_selected")
    full = scenes.photonlm_bake(4_000_000, 64, seed=1, target_error=0.0)
    objects = {name: dict(o) for name, o in full["objects"].items()}
    files = {name: digest(o["path"]) for name, o in objects.items()}
    images = {name: pixels(o["image"]) for name, o in objects.items()}
    full_error = float(full["stats"]["error_estimate"])

    for obj in bpy.context.view_layer.objects:
        obj.select_set(False)
    try:
        res = bpy.ops.photonlm.bake(selected_only=True)
    except RuntimeError as e:  # a background operator's error report raises
        res = str(e)
    checks.check("no selected mesh object" in str(res) and all(digest(o["path"]) == files[n] for n, o in objects.items()),
                 "with nothing selected Bake Selected refuses (%s) and changes no file" % res)

    for name in SELECTED:
        bpy.data.objects[name].select_set(True)
    s = bpy.context.scene.photonlm
    s.seed = 2
    res = bpy.ops.photonlm.bake(selected_only=True)
    from photonlm_blender.writeback import record
    last = record.last()
    checks.check(res == {'FINISHED'} and sorted(last["objects"]) == sorted(SELECTED),
                 "Bake Selected bakes only %s (got %s)" % (SELECTED, sorted(last["objects"])))
    for name, o in objects.items():
        if name in SELECTED:
            continue
        checks.check(digest(o["path"]) == files[name] and np.array_equal(pixels(o["image"]), images[name]),
                     "unselected '%s': file and image unchanged" % name)
    sel_error = float(last["stats"]["error_estimate"])
    for name in SELECTED:
        new = last["objects"][name]
        mask = new["coverage"] > 0.5
        old_rgb = objects[name]["rgb"]
        diff = scenes.mean_relative_error(new["rgb"], old_rgb, mask)
        bound = 3.0 * float(np.hypot(full_error, sel_error))
        checks.check(not np.array_equal(new["rgb"], old_rgb) and diff < bound,
                     "selected '%s': new lightmap, mean relative difference to the full bake %.4f < %.4f"
                     % (name, diff, bound))
    checks.finish()


main()
