"""Screenshots of glass and metal baked in a real Blender window (Xvfb is enough): three scenes of
blend_tests/specular_scenes.py, each baked with the add-on and shown in Material Preview with the
scene's lights and world and Viewport Preview on Lightmaps:
    glass_caustic   a glass sphere on a white floor under a sun: a bright shadow with the caustic
    gold_sphere     a gold metal sphere on a white floor: gold light around it
    glazed_room     a room lit through a glazed window, a gold and a glass sphere inside

    PHOTONLM_LIBRARY=/path/to/build/lib/libphotonlm.so PHOTONLM_SOURCE_DIR=/path/to/repo \\
    xvfb-run -a -s "-screen 0 1600x1000x24" \\
        blender --factory-startup --python docs/make_specular_screenshots.py -- [OUT_DIR]

writes <scene>.png and <scene>_preview_off.png into OUT_DIR (default /tmp/specular_shots), and
with PHOTONLM_DOC_SAVE=1 copies glass_caustic.png and glazed_room.png to docs/images/.
"""
import os
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import window_shots as ws  # noqa: E402
from window_shots import biggest_area, fail  # noqa: E402

ws.NAME = "make_specular_screenshots"
SRC = ws.SRC
PHOTONS = int(os.environ.get("PHOTONLM_DOC_PHOTONS", 40_000_000))
TARGET = float(os.environ.get("PHOTONLM_DOC_TARGET", 0.02))
SHADER_WAIT = float(os.environ.get("PHOTONLM_DOC_WAIT", 12.0))
argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
OUT = os.path.abspath(argv[0]) if argv else "/tmp/specular_shots"
SAVED = {"glass_caustic": "glass_caustic.png", "glazed_room": "glazed_room.png"}
DOC_WIDTH = 1100


def build(name):
    import specular_scenes as ss
    # The sun shines from +x: the shadows and what the spheres throw into them lie towards -x.
    if name == "glass_caustic":
        ss.glass_sphere_on_floor(res=128)
        return ((-2.4, -2.1, 1.9), (-0.3, 0.0, 0.15), 40.0), 0.01
    if name == "gold_sphere":
        ss.gold_sphere_on_floor(res=128)
        return ((-0.4, -3.0, 1.6), (0.0, 0.0, 0.25), 40.0), 0.01
    ss.glazed_room(res=64, sun_angle=2.0)
    return ((-1.9, -1.9, 1.6), (1.0, 0.2, 0.5), 22.0), TARGET


def bake(name, target):
    import scenes
    s = bpy.context.scene.photonlm
    s.output_dir = os.path.join(OUT, "lightmaps_" + name)
    t0 = time.perf_counter()
    last = scenes.photonlm_bake(PHOTONS, 1024, seed=1, target_error=target)
    ws.log("%s: baked %d objects, %s photons in %.1f s (wall %.1f s), error %.3f"
           % (name, len(last["objects"]), "{:,}".format(int(last["stats"]["photons_emitted"])),
              last["stats"]["seconds_total"], time.perf_counter() - t0, last["stats"]["error_estimate"]))
    for level, text in last["reports"]:
        ws.log("%s: report %s: %s" % (name, level, text))


def save_scaled(src, dst, width):
    """A copy of the PNG src at `width` pixels wide (the docs' images stay small)."""
    img = bpy.data.images.load(src, check_existing=False)
    w, h = img.size
    if w > width:
        img.scale(width, max(1, round(h * width / w)))
    img.filepath_raw = dst
    img.file_format = 'PNG'
    img.save()
    bpy.data.images.remove(img)


def steps():
    sys.path.insert(0, os.path.join(SRC, "blend_tests"))
    os.environ.setdefault("PHOTONLM_SOURCE_DIR", SRC)
    import scenes
    scenes.setup_paths()
    os.makedirs(OUT, exist_ok=True)
    win = bpy.context.window_manager.windows[0]
    screen = win.screen
    area = biggest_area(screen, 'VIEW_3D')
    if area is None:
        fail("no 3D viewport")
    with bpy.context.temp_override(window=win, screen=screen, area=area):
        bpy.ops.screen.screen_full_area()
    yield 1.0
    screen = win.screen
    area = biggest_area(screen, 'VIEW_3D')
    space = area.spaces.active
    space.overlay.show_overlays = False
    space.show_gizmo = False
    space.show_region_header = False
    space.show_region_toolbar = False
    space.show_region_ui = False
    for name in ("glass_caustic", "gold_sphere", "glazed_room"):
        view, target = build(name)
        for m in bpy.data.materials:  # Eevee: glass refracts what is behind it in screen space
            if m.node_tree and any(n.bl_idname == 'ShaderNodeBsdfGlass' for n in m.node_tree.nodes):
                m.blend_method = 'OPAQUE'
        ev = bpy.context.scene.eevee
        ev.use_ssr = True
        ev.use_ssr_refraction = True
        ev.use_soft_shadows = True
        bake(name, target)
        space.shading.type = 'MATERIAL'
        space.shading.use_scene_lights = True
        space.shading.use_scene_world = True
        ws.look(space, *view)
        for o in bpy.context.view_layer.objects:
            o.select_set(False)
        for mode, suffix in (('LIGHTMAP', ""), ('OFF', "_preview_off")):
            bpy.context.scene.photonlm.preview_mode = mode
            area.tag_redraw()
            yield SHADER_WAIT
            path = ws.shot(win, screen, area, os.path.join(OUT, name + suffix + ".png"))
            if not suffix and name in SAVED and os.environ.get("PHOTONLM_DOC_SAVE"):
                dst = os.path.join(SRC, "docs", "images", SAVED[name])
                save_scaled(path, dst, DOC_WIDTH)
                ws.log("wrote %s" % dst)
    yield 0.5
    bpy.ops.wm.quit_blender()


def main():
    bpy.context.preferences.view.show_splash = False
    ws.register_addon()
    ws.run(steps)


main()
