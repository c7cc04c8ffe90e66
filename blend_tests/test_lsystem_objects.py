"""L-system objects through the add-on: presets, engine-made previews, bakes through OLs.

Expected:
- bpy.ops.photonlm.add_lsystem adds each preset (SIERPINSKI, SYMPODIAL_TREE, BUSH) with a
  non-empty, capped preview mesh made by the engine;
- rules with a syntax error are refused with the engine's line/column message, and Blender goes on;
- a bake with a sympodial tree over a lit floor: the report says the tree was traced from its
  rules; the tree's preview gets the colour attribute `photonlm_light`, finite, with upward
  vertices brighter than downward ones under a high sun; the 2 x 2 m floor under the tree is
  darker than the same floor without the tree (its shadow), by more than 5 %.
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402


def main():
    checks = scenes.Checks("lsystem_objects")
    scenes.setup_paths()
    scenes.clear_scene()
    for preset in ('SIERPINSKI', 'BUSH', 'SYMPODIAL_TREE'):
        before = set(bpy.data.objects.keys())
        res = bpy.ops.photonlm.add_lsystem(preset=preset)
        new = [bpy.data.objects[n] for n in set(bpy.data.objects.keys()) - before]
        ok = res == {'FINISHED'} and len(new) == 1 and len(new[0].data.polygons) > 0
        checks.check(ok, "preset %s: added with a preview of %s triangles"
                     % (preset, len(new[0].data.polygons) if new else "no"))
        if preset != 'SYMPODIAL_TREE':
            for o in new:
                bpy.data.objects.remove(o)
    tree = bpy.context.active_object
    tree.data.materials.append(scenes.diffuse_material("bark", (0.5, 0.4, 0.3)))

    rules = tree.photonlm.lsystem.rules
    tree.photonlm.lsystem.rules = "axiom: A\nA -> F((1\n"
    try:
        res = bpy.ops.photonlm.update_lsystem()
    except RuntimeError as e:  # background mode: the operator's error report raises
        res = str(e)
    checks.check(res != {'FINISHED'} and "line 2" in str(res), "broken rules refused: %s" % str(res).strip()[:160])
    tree.photonlm.lsystem.rules = rules
    checks.check(bpy.ops.photonlm.update_lsystem() == {'FINISHED'}, "rules restored, preview rebuilt")

    floor = scenes.plane("floor", scenes.diffuse_material("floor_mat", (0.8, 0.8, 0.8)), size=2.0, resolution=32)
    scenes.add_light("sun", 'SUN', (0, 0, 10), rotation=(math.radians(10), 0, 0), energy=4.0, angle=0.05)
    scenes.set_world_color((0.2, 0.25, 0.3))
    bpy.context.scene.photonlm.output_dir = scenes.out_dir("lsystem")
    last = scenes.photonlm_bake(1_000_000, 8, seed=3, target_error=0.0)
    reports = [t for _level, t in last["reports"]]
    checks.check(tree.name in last.get("lsystems", []) and any("traced from its rules" in t for t in reports),
                 "the tree was traced from its rules")
    attr = tree.data.color_attributes.get("photonlm_light")
    checks.check(attr is not None, "the tree's preview has the colour attribute photonlm_light")
    if attr is not None:
        n = len(tree.data.vertices)
        col = np.empty(n * 4, np.float32)
        attr.data.foreach_get("color", col)
        col = col.reshape(-1, 4)[:, :3]
        nrm = np.empty(n * 3, np.float32)
        tree.data.vertices.foreach_get("normal", nrm)
        nz = nrm.reshape(-1, 3)[:, 2]
        up, down = col[nz > 0.7].mean(), col[nz < -0.7].mean()
        checks.check(bool(np.all(np.isfinite(col))) and up > down,
                     "tree light finite; upward vertices %.3f brighter than downward %.3f" % (up, down))
    with_tree = np.asarray(last["objects"]["floor"]["rgb"]).mean()
    tree.hide_render = True
    bare = scenes.photonlm_bake(1_000_000, 8, seed=3, target_error=0.0)
    without = np.asarray(bare["objects"]["floor"]["rgb"]).mean()
    checks.check(with_tree < 0.95 * without, "the tree shades the floor: mean %.4f with, %.4f without"
                 % (with_tree, without))
    checks.finish()


main()
