"""Screenshots for docs/user-guide.md, taken in a real Blender window.

Builds a Cornell box, bakes it with the PhotonLM add-on (bpy.ops.photonlm.bake), then,
once the UI is drawn, shows Render Properties > PhotonLM Lightmaps and the baked box in
the viewport and saves into docs/images/:

    window.png                the whole Blender window: panel and baked box
    panel.png                 the Properties editor (its default width) with the PhotonLM Lightmaps panel
    panel_baking.png          the same during a bake: the progress bar, the stage and the time left
    statusbar_baking.png      the status bar during that bake: its progress bar (the bottom of
                              window_baking.png, which is removed)
    viewport_preview_on.png   the viewport, Material Preview, Preview Lightmaps on
    viewport_preview_off.png  the same view with Preview Lightmaps off (Eevee, no GI)

Run (needs an X display; Xvfb is enough; $PHOTONLM_SHOT_DIR writes elsewhere than docs/images):

    PHOTONLM_LIBRARY=/path/to/build/lib/libphotonlm.so PHOTONLM_SOURCE_DIR=/path/to/repo \\
    xvfb-run -a -s "-screen 0 1600x1000x24" \\
        blender --factory-startup --python docs/make_screenshots.py

Exits non-zero with a message if the add-on cannot be imported, the bake fails or a
screenshot cannot be written.
"""
import math
import os
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import window_shots as ws  # noqa: E402
from window_shots import biggest_area, fail, register_addon, window_region  # noqa: E402

ws.NAME = "make_screenshots"
PHOTONS = int(os.environ.get("PHOTONLM_DOC_PHOTONS", 20_000_000))
PANEL_UP = 11  # scroll steps up from the bottom of Render Properties: the panel's header on top
SHADER_WAIT = float(os.environ.get("PHOTONLM_DOC_WAIT", 20.0))  # seconds for Eevee to compile shaders


SRC = ws.SRC
IMAGES = os.environ.get("PHOTONLM_SHOT_DIR") or os.path.join(os.path.dirname(os.path.abspath(__file__)), "images")


# ---- the scene ---------------------------------------------------------------------------------

def principled(name, color):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = tuple(color) + (1.0,)
    bsdf.inputs["Roughness"].default_value = 0.9
    bsdf.inputs["Specular"].default_value = 0.1
    mat.diffuse_color = tuple(color) + (1.0,)
    return mat


def mesh_object(name, verts, faces, material):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    mesh.uv_layers.new(name="UVMap")  # the artist's texture UVs: the bake leaves them alone
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def box(name, center, half, height, angle, material):
    c, s = math.cos(angle), math.sin(angle)
    verts = []
    for z in (0.0, height):
        for (x, y) in ((-half, -half), (half, -half), (half, half), (-half, half)):
            verts.append((center[0] + c * x - s * y, center[1] + s * x + c * y, z))
    faces = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
    return mesh_object(name, verts, faces, material)


def cornell_box():
    """A 2 m Cornell box (x, y in [-1, 1], z in [0, 2], open towards -y); each wall and box is
    its own object with its own Principled material and no lightmap UV map yet."""
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.lights,
                 bpy.data.cameras):
        for item in list(coll):
            coll.remove(item)
    scene = bpy.context.scene
    world = scene.world or bpy.data.worlds.new("World")
    scene.world = world
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    world.color = (0, 0, 0)
    white, red, green = (0.73, 0.73, 0.73), (0.63, 0.065, 0.05), (0.14, 0.45, 0.09)
    walls = {
        "Floor": ([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], white),
        "Ceiling": ([(-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)], white),
        "Back": ([(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)], white),
        "Left": ([(-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)], red),
        "Right": ([(1, 1, 0), (1, -1, 0), (1, -1, 2), (1, 1, 2)], green),
    }
    for name, (verts, color) in walls.items():
        mesh_object(name, verts, [(0, 1, 2, 3)], principled(name + " Paint", color))
    box("Short Box", (0.35, -0.3), 0.3, 0.6, math.radians(-17), principled("Short Box Paint", white))
    box("Tall Box", (-0.35, 0.35), 0.3, 1.2, math.radians(20), principled("Tall Box Paint", white))
    light = bpy.data.lights.new("Ceiling Light", 'AREA')
    light.shape = 'SQUARE'
    light.size = 0.5
    light.energy = 40.0  # W, as in Cycles
    obj = bpy.data.objects.new("Ceiling Light", light)
    obj.location = (0.0, 0.0, 1.98)
    scene.collection.objects.link(obj)
    bpy.context.view_layer.update()


def bake():
    settings = bpy.context.scene.photonlm
    settings.photons = PHOTONS
    t0 = time.perf_counter()
    try:
        result = bpy.ops.photonlm.bake()
    except RuntimeError as e:  # an ERROR report of the operator
        fail("bake failed: %s" % e)
    if result != {'FINISHED'}:
        fail("bake returned %s" % result)
    from photonlm_blender.writeback import record
    last = record.last()
    print("make_screenshots: baked %d objects, %s photons in %.1f s (wall %.1f s), output %s"
          % (len(last["objects"]), "{:,}".format(int(last["stats"]["photons_emitted"])),
             last["stats"]["seconds_total"], time.perf_counter() - t0, last["output_dir"]), flush=True)
    for level, text in last["reports"]:
        print("make_screenshots: report %s: %s" % (level, text), flush=True)
    missing = [o.name for o in bpy.data.objects if o.type == 'MESH' and o.name + "_lightmap" not in bpy.data.images]
    if missing:
        fail("no lightmap image for %s" % ", ".join(missing))


# ---- the UI ------------------------------------------------------------------------------------

def setup_ui():
    """Render tab in the Properties editor, the viewport looking into the box."""
    win = bpy.context.window_manager.windows[0]
    screen = win.screen
    view3d = biggest_area(screen, 'VIEW_3D')
    props = biggest_area(screen, 'PROPERTIES')
    if view3d is None or props is None:
        fail("no 3D viewport or Properties editor in the window")
    # The Active Object sub-panel shows the floor's lightmap.
    vl = bpy.context.view_layer
    for o in vl.objects:
        o.select_set(False)
    floor = bpy.data.objects["Floor"]
    floor.select_set(True)
    vl.objects.active = floor

    props.spaces.active.context = 'RENDER'

    ws.cornell_view(view3d)
    for area in screen.areas:
        area.tag_redraw()
    return win, screen, view3d, props


def heighten(win, screen, props, pixels):
    """Move the edge between the Outliner and the Properties editor up, so the whole panel fits
    (the cursor must sit on that edge, warped there a step before)."""
    ws.area_move(win, screen, props.x + props.width // 2, props.y + props.height, pixels)


def crop_bottom(path, rows, name):
    """Save the bottom `rows` rows of the image at path as `name` in IMAGES; remove path."""
    full = bpy.data.images.load(path)
    w, h = full.size
    px = np.empty(w * h * 4, np.float32)
    full.pixels.foreach_get(px)
    part = bpy.data.images.new(name, w, rows, alpha=False)
    part.pixels.foreach_set(px[:w * rows * 4])  # Blender's rows start at the bottom
    part.filepath_raw = os.path.join(IMAGES, name)
    part.file_format = 'PNG'
    part.save()
    bpy.data.images.remove(full)
    bpy.data.images.remove(part)
    os.remove(path)
    ws.log("wrote %s" % os.path.join(IMAGES, name))


def shot(win, screen, area, name):
    return ws.shot(win, screen, area, os.path.join(IMAGES, name))


def steps():
    """Generator of the UI steps; yields the seconds to wait before the next step."""
    win, screen, view3d, props = setup_ui()
    win.cursor_warp(props.x + props.width // 2, props.y + props.height)
    yield 0.5
    heighten(win, screen, props, 120)
    yield 0.5
    # Park the cursor over the empty part of the outliner: no tooltip in the screenshots.
    outliner = biggest_area(screen, 'OUTLINER')
    if outliner is not None:
        win.cursor_warp(outliner.x + outliner.width // 2, outliner.y + outliner.height // 2)
    yield 1.0
    ws.scroll(win, screen, props)
    ws.scroll(win, screen, props, down=False, steps=PANEL_UP)  # the PhotonLM panel's top in view
    bpy.context.scene.photonlm.preview = True
    yield SHADER_WAIT
    shot(win, screen, None, "window.png")
    shot(win, screen, props, "panel.png")
    shot(win, screen, view3d, "viewport_preview_on.png")
    bpy.context.scene.photonlm.preview = False
    yield SHADER_WAIT
    shot(win, screen, view3d, "viewport_preview_off.png")
    # A bake as one starts it from the panel (modal, on a worker thread), photographed halfway.
    settings = bpy.context.scene.photonlm
    settings.photons, settings.target_error, settings.time_budget = 0, 0.002, 12.0
    ws.scroll(win, screen, props, down=False)
    with bpy.context.temp_override(window=win, screen=screen, area=props, region=window_region(props)):
        bpy.ops.photonlm.bake('INVOKE_DEFAULT')
    yield 6.0
    shot(win, screen, props, "panel_baking.png")
    crop_bottom(shot(win, screen, None, "window_baking.png"), 28, "statusbar_baking.png")
    yield 10.0
    bpy.ops.wm.quit_blender()


def main():
    bpy.context.preferences.view.show_splash = False
    register_addon()
    os.makedirs(IMAGES, exist_ok=True)
    cornell_box()
    bake()
    ws.run(steps)


main()
