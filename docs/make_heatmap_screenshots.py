"""Screenshots of the error heat map and the Last Bake box for docs/user-guide.md, taken in a
real Blender window as an artist would see them.

Builds a small scene with Blender's own operators (a floor, three boxes, a smooth UV sphere,
a sun and a blue-grey world; no lightmap UV maps: the bake makes them), gives the sphere a
lightmap far too fine for a short bake (Resolution 512, Time Budget 4 s), bakes it with the
PhotonLM add-on, switches the viewport to Material Preview with Preview = Error and saves
into $PHOTONLM_SHOT_DIR (default docs/images). How many photons 4 s buy depends on the machine,
so the figures and the colours differ from run to run:

    error_heatmap.png             the viewport: the per-texel error heat map
    error_heatmap_lightmaps.png   the same view with Preview = Lightmaps
    panel_quality.png             the Properties editor: Render > PhotonLM Lightmaps, Last Bake box

Run (needs an X display; Xvfb is enough):

    PHOTONLM_LIBRARY=/path/to/build/lib/libphotonlm.so PHOTONLM_SOURCE_DIR=/path/to/repo \\
    xvfb-run -a -s "-screen 0 1600x1000x24" \\
        blender --factory-startup --python docs/make_heatmap_screenshots.py
"""
import math
import os
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import window_shots as ws  # noqa: E402
from window_shots import area_move, biggest_area, fail, register_addon  # noqa: E402

ws.NAME = "make_heatmap_screenshots"
SHADER_WAIT = float(os.environ.get("PHOTONLM_DOC_WAIT", 15.0))  # seconds for Eevee to compile shaders
WIDEN = int(os.environ.get("PHOTONLM_DOC_WIDEN", 0))  # pixels added to the Properties editor's width


SHOTS = os.environ.get("PHOTONLM_SHOT_DIR") or os.path.join(ws.SRC, "docs", "images")


def principled(name, color):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = tuple(color) + (1.0,)
    bsdf.inputs["Roughness"].default_value = 0.8
    return mat


def build_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    scene = bpy.context.scene
    world = scene.world or bpy.data.worlds.new("World")
    scene.world = world
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.35, 0.45, 0.6, 1.0)
    bg.inputs["Strength"].default_value = 0.4

    def add(op, name, material, **kw):
        op(**kw)
        obj = bpy.context.active_object
        obj.name = name
        obj.data.materials.append(material)
        return obj

    add(bpy.ops.mesh.primitive_plane_add, "Floor", principled("Floor Paint", (0.7, 0.7, 0.68)), size=8.0)
    for i, (x, y, s, h, a) in enumerate(((-1.6, 0.8, 0.6, 1.2, 20), (1.5, 1.2, 0.5, 0.8, -15),
                                         (0.4, -1.5, 0.4, 0.4, 40))):
        box = add(bpy.ops.mesh.primitive_cube_add, "Box %d" % (i + 1),
                  principled("Box %d Paint" % (i + 1), ((0.8, 0.3, 0.2), (0.3, 0.5, 0.8), (0.8, 0.8, 0.75))[i]),
                  size=1.0, location=(x, y, h / 2))
        box.scale = (2 * s, 2 * s, h)
        box.rotation_euler = (0, 0, math.radians(a))
    sphere = add(bpy.ops.mesh.primitive_uv_sphere_add, "Sphere", principled("Sphere Paint", (0.75, 0.75, 0.75)),
                 segments=48, ring_count=24, radius=0.7, location=(0.1, 0.4, 0.7))
    bpy.ops.object.shade_smooth()
    sphere.photonlm.resolution = 512  # far finer than the others: too few photons reach each texel
    sun = bpy.data.lights.new("Sun", 'SUN')
    sun.energy = 4.0
    sun.angle = math.radians(3.0)
    sun_obj = bpy.data.objects.new("Sun", sun)
    sun_obj.rotation_euler = (math.radians(-45), 0.0, math.radians(35))  # shadows towards the camera
    scene.collection.objects.link(sun_obj)
    settings = scene.photonlm
    settings.time_budget = 4.0
    bpy.context.view_layer.update()


def bake():
    t0 = time.perf_counter()
    try:
        result = bpy.ops.photonlm.bake()
    except RuntimeError as e:
        fail("bake failed: %s" % e)
    if result != {'FINISHED'}:
        fail("bake returned %s" % result)
    from photonlm_blender.writeback import record
    last = record.last()
    s = last["stats"]
    print("make_heatmap_screenshots: baked %d objects in %.1f s (wall %.1f s): error %.2f %%, median %.1f %%, "
          "p95 %.1f %%, above 2x target %.1f %%" % (len(last["objects"]), s["seconds_total"], time.perf_counter() - t0,
                                                   100 * s["error_estimate"], 100 * s["error_median"],
                                                   100 * s["error_p95"], 100 * s["error_above"]), flush=True)
    for name, o in sorted(last["objects"].items()):
        print("make_heatmap_screenshots:   %s %s: %.1f %% of %d texels above" % (name, o["size"], 100 * o["error_above"],
                                                                             o["texels"]), flush=True)
    for level, text in last["reports"]:
        print("make_heatmap_screenshots: report %s: %s" % (level, text), flush=True)


def setup_ui():
    win = bpy.context.window_manager.windows[0]
    screen = win.screen
    view3d = biggest_area(screen, 'VIEW_3D')
    props = biggest_area(screen, 'PROPERTIES')
    vl = bpy.context.view_layer
    for o in vl.objects:
        o.select_set(False)
    sphere = bpy.data.objects["Sphere"]
    sphere.select_set(True)
    vl.objects.active = sphere
    props.spaces.active.context = 'RENDER'
    space = view3d.spaces.active
    space.shading.type = 'MATERIAL'
    space.overlay.show_overlays = False
    space.show_gizmo = False
    space.lens = 50.0
    r3d = space.region_3d
    r3d.view_perspective = 'PERSP'
    r3d.view_location = (0.0, 0.2, 0.4)
    r3d.view_rotation = (0.82, 0.45, 0.17, 0.31)
    r3d.view_distance = 8.5
    for area in screen.areas:
        area.tag_redraw()
    return win, screen, view3d, props


def shot(win, screen, area, name):
    ws.shot(win, screen, area, os.path.join(SHOTS, name))


def steps():
    win, screen, view3d, props = setup_ui()
    if WIDEN:
        win.cursor_warp(props.x - 1, props.y + props.height // 2)
        yield 0.5
        area_move(win, screen, props.x - 1, props.y + props.height // 2, -WIDEN)
    win.cursor_warp(props.x + props.width // 2, props.y + props.height)
    yield 0.5
    area_move(win, screen, props.x + props.width // 2, props.y + props.height, 120)
    yield 0.5
    outliner = biggest_area(screen, 'OUTLINER')
    if outliner is not None:
        win.cursor_warp(outliner.x + outliner.width // 2, outliner.y + outliner.height // 2)
    yield 1.0
    bpy.context.scene.photonlm.preview_mode = 'ERROR'
    ws.scroll(win, screen, props)
    yield SHADER_WAIT
    shot(win, screen, props, "panel_quality.png")
    shot(win, screen, view3d, "error_heatmap.png")
    bpy.context.scene.photonlm.preview_mode = 'LIGHTMAP'
    yield SHADER_WAIT
    shot(win, screen, view3d, "error_heatmap_lightmaps.png")
    yield 0.5
    bpy.ops.wm.quit_blender()


def main():
    bpy.context.preferences.view.show_splash = False
    register_addon()
    os.makedirs(SHOTS, exist_ok=True)
    build_scene()
    bake()
    ws.run(steps)


main()
