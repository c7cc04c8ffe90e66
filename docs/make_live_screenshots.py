"""Screenshots for docs/user-guide.md "Watching a bake": the viewport (Material Preview) during a
modal bake of the Cornell box with Refresh While Baking at 1 s, a few seconds in (the direct pass:
direct light only) and later (photons too), saved into docs/images/ as viewport_live_early.png and
viewport_live_later.png; then the bake is cancelled (the materials return to what they were) and
Blender quits. A short bake first wires the materials and lets Eevee compile their shaders (the
live images reuse them), so that the early screenshot shows the lightmaps and not Eevee's
stand-in while it compiles.

    PHOTONLM_LIBRARY=/path/to/build/lib/libphotonlm.so PHOTONLM_SOURCE_DIR=/path/to/repo \\
    xvfb-run -a -s "-screen 0 1600x1000x24" \\
        blender --factory-startup --python docs/make_live_screenshots.py

$PHOTONLM_SHOT_DIR writes elsewhere than docs/images; $PHOTONLM_DOC_WAIT (s, default 30) is the
wait for Eevee's shaders and the time between the two screenshots.
"""
import os
import sys

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import window_shots as ws  # noqa: E402
from window_shots import biggest_area, fail, register_addon, window_region  # noqa: E402

ws.NAME = "make_live_screenshots"
IMAGES = os.environ.get("PHOTONLM_SHOT_DIR") or os.path.join(HERE, "images")
WAIT = float(os.environ.get("PHOTONLM_DOC_WAIT", 30.0))
EARLY = 5.0  # seconds into the bake of the first screenshot


def setup_view(screen):
    view3d = biggest_area(screen, 'VIEW_3D')
    if view3d is None:
        fail("no 3D viewport in the window")
    ws.cornell_view(view3d)
    return view3d


def steps():
    from photonlm_blender.operators import bake as operators
    win = bpy.context.window_manager.windows[0]
    screen = win.screen
    view3d = setup_view(screen)
    settings = bpy.context.scene.photonlm
    settings.preview_mode = 'LIGHTMAP'
    yield WAIT  # Eevee compiles the preview's shaders
    settings.photons, settings.target_error, settings.time_budget = 0, 0.001, 3 * WAIT
    settings.live_preview = 1.0
    with bpy.context.temp_override(window=win, screen=screen, area=view3d, region=window_region(view3d)):
        bpy.ops.photonlm.bake('INVOKE_DEFAULT')
    yield EARLY
    op = operators._running
    if op is None or op._live is None or op._live.refreshes == 0:
        fail("no live refresh after %.0f s" % EARLY)
    ws.log("early: %d refreshes, %d photons" % (op._live.refreshes, op._live.photons))
    ws.shot(win, screen, view3d, os.path.join(IMAGES, "viewport_live_early.png"))
    yield WAIT
    op = operators._running
    if op is None:
        fail("the bake ended before the second screenshot")
    ws.log("later: %d refreshes, %d photons" % (op._live.refreshes, op._live.photons))
    ws.shot(win, screen, view3d, os.path.join(IMAGES, "viewport_live_later.png"))
    op._cancel.set()
    while operators._running is not None:
        yield 0.2
    yield 1.0
    bpy.ops.wm.quit_blender()


def main():
    bpy.context.preferences.view.show_splash = False
    register_addon()
    sys.path.insert(0, os.path.join(ws.SRC, "blend_tests"))
    import scenes
    os.makedirs(IMAGES, exist_ok=True)
    scenes.clear_scene()
    scenes.cornell_box()
    settings = bpy.context.scene.photonlm
    settings.photons, settings.target_error = 1_000_000, 0.0
    if bpy.ops.photonlm.bake() != {'FINISHED'}:
        fail("the first bake failed")
    ws.run(steps)


main()
