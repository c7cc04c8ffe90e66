"""A scene that nothing lights is refused, and the refusal changes nothing.

A lit bake first (floor and cube under a sun) leaves images, files, wired materials and an
automatic UV map behind; an object without a 'lightmap' UV map is added. Then the sun is hidden,
a 0 W point light and a black area light are added and the world is black:
- the add-on refuses before exporting: bpy.ops.photonlm.bake() raises with 'nothing lights the
  scene' naming the hidden, powerless and black lights; images, materials, UV maps, files and
  the statistics are as they were;
- with the add-on's check bypassed the engine refuses the same scene ('bake refused: nothing
  lights the scene'); the UV map the job made is undone and nothing else changes;
- what counts as light: a world colour, an emissive material, a visible sun; a portal or a
  light on a hidden object does not.
"""
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402
import unchanged  # noqa: E402

import bpy  # noqa: E402


def bake_error():
    """The text of the error bpy.ops.photonlm.bake() raises, or None when it finishes."""
    try:
        bpy.ops.photonlm.bake()
    except RuntimeError as e:
        return str(e)
    return None


def main():
    t_start = time.perf_counter()
    scenes.setup_paths()
    from photonlm_blender.export import scene as export
    from photonlm_blender.uv import uvmaps
    from photonlm_blender.writeback import images
    checks = scenes.Checks("no_light_refusal")
    scene = scenes.clear_scene()
    scene.photonlm.output_dir = scenes.out_dir("no_light") + "/"
    scenes.plane("floor", scenes.diffuse_material("floor_mat", (0.7, 0.7, 0.7)), size=4.0, resolution=32)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0, 0, 0.5))
    cube = bpy.context.object
    cube.name = "cube"
    cube.data.materials.append(scenes.diffuse_material("cube_mat", (0.6, 0.5, 0.4)))
    sun = scenes.add_light("sun", 'SUN', (0, 0, 5), rotation=(0.4, 0.2, 0), energy=3.0)
    scenes.photonlm_bake(300_000, 8, seed=1, target_error=0.05)
    checks.check(bpy.data.images.get("cube_lightmap") is not None, "the lit bake made the cube's lightmap")
    checks.check(export.light_sources(bpy.context) == ["light 'sun'"], "the sun lights the scene (%s)"
                 % export.light_sources(bpy.context))

    late = scenes.quads_object("late", [((3, 3, 0), (3.5, 3, 0), (3.5, 3.5, 0), (3, 3.5, 0), (0, 0, 1, 1))],
                               scenes.diffuse_material("late_mat", (0.5,) * 3), 16)
    late.data.uv_layers.remove(late.data.uv_layers["lightmap"])  # a bake would make one
    sun.hide_render = True
    scenes.add_light("dim", 'POINT', (0, 0, 2), energy=0.0)
    scenes.add_light("black", 'AREA', (0, 0, 2), energy=100.0, color=(0.0, 0.0, 0.0))
    bpy.context.view_layer.update()
    folder = images.output_directory(scene)
    before = unchanged.snapshot(folder)

    # -- the add-on refuses before anything changes ---------------------------------------------------------------
    t0 = time.perf_counter()
    error = bake_error()
    seconds = time.perf_counter() - t0
    checks.check(error is not None and "nothing lights the scene" in error,
                 "unlit scene refused by the add-on (%.2f s): %s" % (seconds, error))
    checks.check(error is not None and "'sun' is hidden" in error and "'dim' has no power" in error
                 and "'black' is black" in error, "the message names the hidden, powerless and black lights")
    diff = unchanged.differences(before, unchanged.snapshot(folder))
    checks.check(not diff, "nothing changed: images, materials, UV maps, files, statistics %s" % diff)
    checks.check("lightmap" not in late.data.uv_layers, "no UV map made for the unbaked object")

    # -- the engine refuses too (the last guard) -------------------------------------------------------------------
    real, real_undo = export.light_sources, uvmaps.undo
    undone = []

    def undo(changes):
        undone.append(len(changes))
        return real_undo(changes)
    export.light_sources = lambda context, limit=1: ["a light the add-on imagines"]
    uvmaps.undo = undo
    try:
        t0 = time.perf_counter()
        error = bake_error()
        seconds = time.perf_counter() - t0
    finally:
        export.light_sources, uvmaps.undo = real, real_undo
    checks.check(error is not None and "bake refused: nothing lights the scene" in error,
                 "with the add-on's check bypassed the engine refuses (%.2f s): %s" % (seconds, error))
    checks.check(sum(undone) >= 1, "the job had made a UV map before the engine refused (undone: %s)" % undone)
    diff = unchanged.differences(before, unchanged.snapshot(folder))
    checks.check(not diff, "nothing changed after the engine's refusal (the UV map it made is undone) %s" % diff)

    # -- what counts as light ----------------------------------------------------------------------------------------------
    scenes.set_world_color((0.2, 0.3, 0.4), 1.0)
    found = export.light_sources(bpy.context, limit=0)
    checks.check(found == ["the world"], "a world colour lights the scene (%s)" % found)
    scenes.set_world_color((0.2, 0.3, 0.4), 0.0)
    checks.check(export.light_sources(bpy.context, limit=0) == [], "a world of strength 0 does not")
    portal = scenes.add_light("window", 'AREA', (0, 0, 3), energy=0.0, size=1.0)
    portal.data.cycles.is_portal = True
    bpy.context.view_layer.update()
    checks.check(export.light_sources(bpy.context, limit=0) == [], "a portal does not light the scene")
    lamp = scenes.emission_material("lamp_mat", (1.0, 0.9, 0.8), 5.0)
    late.data.materials[0] = lamp
    found = export.light_sources(bpy.context, limit=0)
    checks.check(found == ["material 'lamp_mat' on 'late'"], "an emissive material lights the scene (%s)" % found)
    late.hide_render = True
    bpy.context.view_layer.update()
    checks.check(export.light_sources(bpy.context, limit=0) == [], "not on an object hidden in renders")
    sun.hide_render = False
    bpy.context.view_layer.update()
    checks.check(export.light_sources(bpy.context, limit=0) == ["light 'sun'"], "the visible sun again")
    print("no_light_refusal: %.1f s" % (time.perf_counter() - t_start))
    checks.finish()


try:
    main()
except Exception:
    import traceback
    traceback.print_exc()
    sys.exit(1)
