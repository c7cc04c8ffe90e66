"""Screenshot for docs/user-guide.md "Directional lightmaps": the brick wall of blend_tests/scenes.py
(brick_wall: a tangent-space normal map of bevelled bricks through a Normal Map node into the
Principled BSDF's Normal) on a floor under a sun 55 degrees from the wall's normal and a blue sky,
baked once with Directional on, then seen in Material Preview with the preview reading the plain
lightmap (Directional off: what a bake without Directional shows, bit for bit the same lightmap)
and the directional one (the node group 'PhotonLM Directional' at the normal map's normals).

    PHOTONLM_SOURCE_DIR=$PWD PHOTONLM_LIBRARY=$PWD/build/addon_stage/photonlm_blender/lib/photonlm/libphotonlm.so \\
        scripts/in_root.sh /var/cache/photonlm/roots/sid \\
        xvfb-run -a -s "-screen 0 1600x1000x24" blender --factory-startup \\
        --python docs/make_directional_screenshots.py -- OUT_DIR

Writes directional_off_on.png into OUT_DIR (default docs/images): the viewport without and with
the directions, the middle of each, side by side.
"""
import os
import sys

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import window_shots as ws  # noqa: E402
from window_shots import fail  # noqa: E402

ws.NAME = "make_directional_screenshots"
OUT = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv[:-1] else os.path.join(HERE, "images")
SHADER_WAIT = float(os.environ.get("PHOTONLM_DOC_WAIT", 20.0))  # EEVEE compiles the preview's shaders
EYE, TARGET, LENS = (0.9, -2.3, 1.45), (0.0, 0.0, 0.85), 36.0
KEEP = 0.62  # the middle share of each shot's width in the side-by-side picture
GAP = 8      # white pixels between the two


def build():
    import scenes
    scene = scenes.clear_scene()
    mat = scenes.brick_material("bricks", scenes.normal_map_image("bricks_normal", scenes.brick_normals(96)))
    next(n for n in mat.node_tree.nodes if n.bl_idname == 'ShaderNodeTexImage').interpolation = 'Linear'
    scenes.brick_wall(96, mat)
    scenes.quads_object("floor", [((-1.5, -2.5, 0), (1.5, -2.5, 0), (1.5, 0, 0), (-1.5, 0, 0), (0, 0, 1, 1))],
                        scenes.diffuse_material("floor", (0.55, 0.55, 0.5)), 64)
    scenes.add_sun(scenes.BRICK_SUN, 3.0, angle=0.01)
    scenes.set_world_color(scenes.BRICK_SKY, 1.0)
    scene.view_settings.view_transform = 'Standard'
    return scene, mat


def feed(materials, directional):
    """The preview reads the directional lightmap (the node group) or the plain one (its image)."""
    from photonlm_blender.preview import live
    for mat in materials:
        live._feed_multiply(mat, from_groups=directional)


def side_by_side(paths, out):
    """The middle KEEP of each PNG's width, side by side with GAP white pixels between, as a PNG."""
    parts = []
    for path in paths:
        image = bpy.data.images.load(path, check_existing=False)
        w, h = image.size
        px = np.empty(w * h * 4, np.float32)
        image.pixels.foreach_get(px)
        bpy.data.images.remove(image)
        px = px.reshape(h, w, 4)
        x0 = int(w * (1.0 - KEEP) / 2)
        parts.append(px[:, x0:x0 + int(w * KEEP)])
    h = min(p.shape[0] for p in parts)
    gap = np.ones((h, GAP, 4), np.float32)
    px = np.concatenate([parts[0][:h], gap, parts[1][:h]], axis=1)
    image = bpy.data.images.new("side_by_side", px.shape[1], h, alpha=False)
    image.pixels.foreach_set(px.ravel())
    image.filepath_raw = out
    image.file_format = 'PNG'
    image.save()
    ws.log("wrote %s" % out)


def steps(materials):
    win = bpy.context.window_manager.windows[0]
    screen = win.screen
    area, space = ws.material_viewport(screen)
    space.shading.use_scene_world = True
    space.show_region_header = False
    if hasattr(space, "show_region_tool_header"):
        space.show_region_tool_header = False
    ws.look(space, EYE, TARGET, LENS)
    yield SHADER_WAIT
    shots = []
    for name, directional in (("off", False), ("on", True)):
        feed(materials, directional)
        yield 3.0
        shots.append(ws.shot(win, screen, area, os.path.join(OUT, "directional_%s.png" % name)))
    side_by_side(shots, os.path.join(OUT, "directional_off_on.png"))
    for path in shots:
        os.remove(path)
    yield 0.5
    bpy.ops.wm.quit_blender()


def main():
    bpy.context.preferences.view.show_splash = False
    ws.register_addon()
    sys.path.insert(0, os.path.join(ws.SRC, "blend_tests"))
    os.makedirs(OUT, exist_ok=True)
    scene, mat = build()
    settings = scene.photonlm
    settings.directional = True
    settings.target_error, settings.photons, settings.direct_samples = 0.0, 2_000_000, 256
    settings.preview_mode = 'LIGHTMAP'
    if bpy.ops.photonlm.bake() != {'FINISHED'}:
        fail("the bake failed")
    ws.log("baked (Directional)")
    ws.run(lambda: steps([mat, bpy.data.materials["floor"]]))


main()
