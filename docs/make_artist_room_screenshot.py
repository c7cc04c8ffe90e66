"""Screenshots of the artist's room (blend_tests/scenes.py: artist_room) baked in a real Blender
window: the room is built with its modifiers, baked with the add-on (automatic lightmap UVs
included), and shown in Material Preview with Preview Lightmaps on from a few viewpoints.

    PHOTONLM_LIBRARY=/path/to/build/lib/libphotonlm.so PHOTONLM_SOURCE_DIR=/path/to/repo \\
    xvfb-run -a -s "-screen 0 1600x1000x24" \\
        blender --factory-startup --python docs/make_artist_room_screenshot.py -- [OUT_DIR]

writes room_inside.png, room_window.png, room_objects.png, room_outside.png, close-ups
(room_suzanne.png, room_table.png, room_reveal.png) and room_inside_preview_off.png into OUT_DIR (default /tmp/artist_room_shots), and with
PHOTONLM_DOC_SAVE=1 copies room_inside.png to docs/images/artist_room.png.
"""
import math
import os
import shutil
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import window_shots as ws  # noqa: E402
from window_shots import biggest_area, fail  # noqa: E402

ws.NAME = "make_artist_room_screenshot"
PHOTONS = int(os.environ.get("PHOTONLM_DOC_PHOTONS", 30_000_000))
TARGET = float(os.environ.get("PHOTONLM_DOC_TARGET", 0.01))
SHADER_WAIT = float(os.environ.get("PHOTONLM_DOC_WAIT", 15.0))
SRC = ws.SRC
argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
OUT = os.path.abspath(argv[0]) if argv else "/tmp/artist_room_shots"

# name: (eye, target, lens)
VIEWS = {
    "room_inside": ((-2.85, -1.5, 1.65), (1.8, 0.5, 0.8), 18.0),
    "room_window": ((-1.0, 0.2, 1.4), (3.0, -0.2, 1.4), 22.0),
    "room_objects": ((0.6, -0.2, 1.5), (-1.2, 1.6, 0.5), 22.0),
    "room_outside": ((9.0, -7.0, 6.0), (0.0, 0.0, 1.2), 35.0),
    "room_suzanne": ((0.7, 0.0, 0.75), (1.6, 0.9, 0.3), 35.0),
    "room_table": ((0.4, -1.9, 1.3), (1.0, -1.2, 0.55), 35.0),
    "room_reveal": ((1.6, -1.3, 1.8), (3.0, 0.0, 2.4), 30.0),
}


def setup():
    sys.path.insert(0, os.path.join(SRC, "blend_tests"))
    os.environ.setdefault("PHOTONLM_SOURCE_DIR", SRC)
    import scenes
    scenes.setup_paths()
    from photonlm_blender import bridge
    from photonlm_blender.writeback import record
    try:
        bridge.get()
    except RuntimeError as e:
        fail(str(e))
    scenes.clear_scene()
    os.makedirs(OUT, exist_ok=True)
    scenes.artist_room(OUT)
    s = bpy.context.scene.photonlm
    s.output_dir = os.path.join(OUT, "lightmaps")
    s.photons = PHOTONS
    s.target_error = TARGET
    t0 = time.perf_counter()
    try:
        result = bpy.ops.photonlm.bake()
    except RuntimeError as e:
        fail("bake failed: %s" % e)
    if result != {'FINISHED'}:
        fail("bake returned %s" % result)
    from photonlm_blender.writeback import record
    last = record.last()
    print("make_artist_room_screenshot: baked %d objects, %s photons in %.1f s (wall %.1f s), error %.3f"
          % (len(last["objects"]), "{:,}".format(int(last["stats"]["photons_emitted"])),
             last["stats"]["seconds_total"], time.perf_counter() - t0, last["stats"]["error_estimate"]), flush=True)
    for level, text in last["reports"]:
        print("make_artist_room_screenshot: report %s: %s" % (level, text), flush=True)


def shot(win, screen, area, name):
    return ws.shot(win, screen, area, os.path.join(OUT, name + ".png"))


def steps():
    win = bpy.context.window_manager.windows[0]
    screen = win.screen
    area = biggest_area(screen, 'VIEW_3D')
    if area is None:
        fail("no 3D viewport")
    # One big viewport: close the other areas' space by maximising the viewport.
    with bpy.context.temp_override(window=win, screen=screen, area=area):
        bpy.ops.screen.screen_full_area()
    yield 1.0
    screen = win.screen
    area = biggest_area(screen, 'VIEW_3D')
    space = area.spaces.active
    space.shading.type = 'MATERIAL'
    space.overlay.show_overlays = False
    space.show_gizmo = False
    space.show_region_header = False
    space.show_region_toolbar = False
    space.show_region_ui = False
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    bpy.context.scene.photonlm.preview = True
    yield SHADER_WAIT
    for name, (eye, target, lens) in VIEWS.items():
        ws.look(space, eye, target, lens)
        area.tag_redraw()
        yield 2.0
        path = shot(win, screen, area, name)
        if name == "room_inside" and os.environ.get("PHOTONLM_DOC_SAVE"):
            dst = os.path.join(SRC, "docs", "images", "artist_room.png")
            shutil.copyfile(path, dst)
            print("make_artist_room_screenshot: wrote %s" % dst, flush=True)
    bpy.context.scene.photonlm.preview = False
    ws.look(space, *VIEWS["room_inside"])
    yield SHADER_WAIT
    shot(win, screen, area, "room_inside_preview_off")
    yield 0.5
    bpy.ops.wm.quit_blender()


def main():
    bpy.context.preferences.view.show_splash = False
    setup()
    ws.run(steps)


main()
