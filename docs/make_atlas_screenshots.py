"""Screenshots of an atlas bake for docs/user-guide.md, taken in a real Blender window.

Builds a floor and 24 cubes and ico spheres of four sizes under a sun (no lightmap UV maps: the
bake makes them), sets Layout = Atlases (Page Size 512, Margin 8, Texel Density 64), bakes with a
Time Budget of 6 s, and saves into $PHOTONLM_SHOT_DIR (default docs/images):

    panel_atlas.png    the Properties editor: Render > PhotonLM Lightmaps, its Lightmaps sub-panel open
    atlas_page.png     the first atlas page in an Image Editor (the blocks with their margins)

Run (needs an X display; Xvfb is enough):

    PHOTONLM_LIBRARY=/path/to/build/lib/libphotonlm.so PHOTONLM_SOURCE_DIR=/path/to/repo \\
    xvfb-run -a -s "-screen 0 1600x1000x24" \\
        blender --factory-startup --python docs/make_atlas_screenshots.py
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import window_shots as ws  # noqa: E402
from window_shots import biggest_area, fail, register_addon  # noqa: E402

ws.NAME = "make_atlas_screenshots"
SHOTS = os.environ.get("PHOTONLM_SHOT_DIR") or os.path.join(ws.SRC, "docs", "images")


def material(name, color):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = tuple(color) + (1.0,)
    return mat


def build_scene():
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    bpy.ops.mesh.primitive_plane_add(size=8.0)
    floor = bpy.context.active_object
    floor.name = "Floor"
    floor.data.materials.append(material("Floor", (0.7, 0.7, 0.7)))
    floor.photonlm.density_scale = 0.5
    for i in range(24):
        s = (0.3, 0.5, 0.7, 0.9)[i % 4]
        x, y = -3.0 + 1.2 * (i % 6), -2.5 + 1.5 * (i // 6)
        if i % 2:
            bpy.ops.mesh.primitive_cube_add(size=s, location=(x, y, s / 2))
        else:
            bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2, radius=s / 2, location=(x, y, s / 2))
        obj = bpy.context.active_object
        obj.name = "Object %02d" % i
        obj.data.materials.append(material("Object %02d" % i, (0.8, 0.5 + 0.02 * i, 0.3)))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.data.energy = 3.0
    sun.rotation_euler = (0.6, 0.3, 0.4)
    bpy.context.scene.collection.objects.link(sun)
    s = bpy.context.scene.photonlm
    s.lightmap_layout = 'ATLAS'
    s.atlas_size = '512'
    s.lightmap_margin = 8
    s.texel_density = 64
    s.time_budget = 6.0
    s.output_dir = os.path.join(bpy.app.tempdir, "atlas_shots")


def open_lightmaps_panel():
    """Draw the Lightmaps sub-panel open (it is closed by default)."""
    from photonlm_blender.ui import panel
    cls = panel.PHOTONLM_PT_output
    bpy.utils.unregister_class(cls)
    cls.bl_options = set()
    bpy.utils.register_class(cls)


def steps():
    win = bpy.context.window_manager.windows[0]
    screen = win.screen
    props = biggest_area(screen, 'PROPERTIES')
    view3d = biggest_area(screen, 'VIEW_3D')
    props.spaces.active.context = 'RENDER'
    bpy.context.view_layer.objects.active = bpy.data.objects["Object 03"]
    yield 1.0
    ws.scroll(win, screen, props)
    yield 1.0
    ws.shot(win, screen, props, os.path.join(SHOTS, "panel_atlas.png"))
    view3d.type = 'IMAGE_EDITOR'
    space = view3d.spaces.active
    space.image = bpy.data.images[bpy.context.scene["photonlm_atlas"]["pages"][0]]
    yield 1.0
    with bpy.context.temp_override(window=win, screen=screen, area=view3d, region=ws.window_region(view3d)):
        bpy.ops.image.view_all(fit_view=True)
    yield 1.0
    ws.shot(win, screen, view3d, os.path.join(SHOTS, "atlas_page.png"))
    yield 0.5
    bpy.ops.wm.quit_blender()


def main():
    bpy.context.preferences.view.show_splash = False
    register_addon()
    os.makedirs(SHOTS, exist_ok=True)
    build_scene()
    try:
        result = bpy.ops.photonlm.bake()
    except RuntimeError as e:
        fail("bake failed: %s" % e)
    if result != {'FINISHED'}:
        fail("bake returned %s" % result)
    open_lightmaps_panel()
    ws.run(steps)


main()
