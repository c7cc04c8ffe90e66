"""Screenshots for docs/user-guide.md "Light groups": the room of blend_tests/scenes.py
light_groups_room (a sun and a sky through a window in Light Group "day", two lamps in "night"),
baked once with the add-on's operator, then relit in Material Preview without baking again: day
only, night only, and half of each with the night tinted warm, each a screenshot of the
viewport, and the whole window (the Light Groups panel with its sliders) at the mix.

    PHOTONLM_SOURCE_DIR=$PWD PHOTONLM_LIBRARY=$PWD/build/addon_stage/photonlm_blender/lib/photonlm/libphotonlm.so \\
        scripts/in_root.sh /var/cache/photonlm/roots/sid \\
        xvfb-run -a -s "-screen 0 1600x1000x24" blender --factory-startup \\
        --python docs/make_light_groups_screenshots.py -- OUT_DIR

Writes light_groups_day.png, light_groups_night.png, light_groups_mix.png (the viewport) and
light_groups_panel.png (the window) into OUT_DIR (default docs/images).
The user guide shows the three viewport shots side by side (light_groups_day_night_mix.png) and
the panel's column of light_groups_panel.png.
"""
import os
import sys

import bpy
from mathutils import Vector

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import window_shots as ws  # noqa: E402
from window_shots import fail  # noqa: E402

ws.NAME = "make_light_groups_screenshots"
OUT = sys.argv[sys.argv.index("--") + 1] if "--" in sys.argv[:-1] else os.path.join(HERE, "images")
SHADER_WAIT = float(os.environ.get("PHOTONLM_DOC_WAIT", 20.0))  # EEVEE compiles the preview's shaders
TARGET = 0.003  # low enough for a clean day layer beside the brighter lamps (docs/design/light-groups.md)
MIXES = (("day", 1.0, 0.0, (1.0, 1.0, 1.0)), ("night", 0.0, 1.0, (1.0, 1.0, 1.0)),
         ("mix", 0.5, 0.5, (1.0, 0.7, 0.45)))


def set_mix(day, night, tint):
    groups = bpy.context.scene.photonlm.light_groups
    groups["day"].strength, groups["night"].strength = day, night
    groups["night"].tint = tint


def steps():
    win = bpy.context.window_manager.windows[0]
    screen = win.screen
    area, space = ws.material_viewport(screen)
    cam = bpy.context.scene.camera
    forward = cam.matrix_world.to_3x3() @ Vector((0, 0, -1))
    ws.look(space, tuple(cam.location), tuple(cam.location + forward), 16.0)
    props = next((a for a in screen.areas if a.type == 'PROPERTIES'), None)
    if props is not None:
        props.spaces.active.context = 'RENDER'
    yield 1.0
    if props is not None:  # down to the PhotonLM panel's Light Groups box
        ws.scroll(win, screen, props)
    yield SHADER_WAIT
    for name, day, night, tint in MIXES:
        set_mix(day, night, tint)
        yield 3.0
        ws.shot(win, screen, area, os.path.join(OUT, "light_groups_%s.png" % name))
        ws.log("%s: day %.1f, night %.1f" % (name, day, night))
    ws.shot(win, screen, None, os.path.join(OUT, "light_groups_panel.png"))
    yield 0.5
    bpy.ops.wm.quit_blender()


def main():
    bpy.context.preferences.view.show_splash = False
    ws.register_addon()
    sys.path.insert(0, os.path.join(ws.SRC, "blend_tests"))
    import scenes
    os.makedirs(OUT, exist_ok=True)
    scene, _, _, _ = scenes.light_groups_room(48, (0.45, 0.6, 1.0))
    settings = scene.photonlm
    settings.target_error, settings.photons = TARGET, 0
    settings.preview_mode = 'LIGHTMAP'
    if bpy.ops.photonlm.bake() != {'FINISHED'}:
        fail("the bake failed")
    ws.log("baked: layers %s" % [g.name for g in settings.light_groups])
    ws.run(steps)


main()
