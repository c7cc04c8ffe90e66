"""What the screenshot scripts in docs/ share: they run in a real Blender window (Xvfb is enough),
register the add-on from the source tree, and take screenshots from a timer once the window is
drawn, step by step (a generator yields the seconds to wait before its next step).

    import window_shots as ws
    ws.NAME = "make_x"                       # prefixes every message
    ws.register_addon()
    ...build and bake...
    ws.run(steps)                            # steps(): a generator of waits; ws.shot(...) inside
"""
import os
import sys

import bpy

NAME = "screenshots"
SRC = os.path.abspath(os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(os.path.dirname(
    os.path.abspath(__file__))))


def log(message):
    print("%s: %s" % (NAME, message), flush=True)


def fail(message):
    print("%s: ERROR: %s" % (NAME, message), file=sys.stderr, flush=True)
    os._exit(1)


def register_addon():
    """Import and register the add-on from SRC/addon (bridge from SRC/python_bridge); fail with a
    message if it or the engine library cannot be loaded."""
    for sub in ("addon", "python_bridge"):
        p = os.path.join(SRC, sub)
        if p not in sys.path:
            sys.path.insert(0, p)
    try:
        import photonlm_blender
    except Exception as e:  # noqa: BLE001
        fail("cannot import the add-on photonlm_blender from %s/addon: %s" % (SRC, e))
    if not hasattr(bpy.types.Scene, "photonlm"):
        photonlm_blender.register()
    from photonlm_blender import bridge
    try:
        bridge.get()
    except RuntimeError as e:
        fail(str(e))
    return photonlm_blender


def biggest_area(screen, kind):
    areas = [a for a in screen.areas if a.type == kind]
    return max(areas, key=lambda a: a.width * a.height) if areas else None


def cornell_view(view3d):
    """The 3D viewport in Material Preview with the scene's lights and world, no overlays, looking
    into the Cornell box of blend_tests/scenes.py."""
    space = view3d.spaces.active
    space.shading.type = 'MATERIAL'
    space.shading.use_scene_lights = True
    space.shading.use_scene_world = True
    space.overlay.show_overlays = False
    space.show_gizmo = False
    space.lens = 60.0
    r3d = space.region_3d
    r3d.view_perspective = 'PERSP'
    r3d.view_location = (0.0, 0.0, 1.0)
    r3d.view_rotation = (0.7071068, 0.7071068, 0.0, 0.0)  # looking along +y, z up
    r3d.view_distance = 3.5


def look(space, eye, target, lens):
    """Point a 3D viewport's view from eye at target with a lens of `lens` mm."""
    from mathutils import Vector
    eye, target = Vector(eye), Vector(target)
    r3d = space.region_3d
    r3d.view_perspective = 'PERSP'
    r3d.view_location = target
    r3d.view_rotation = (target - eye).to_track_quat('-Z', 'Y')
    r3d.view_distance = (target - eye).length
    space.lens = lens
    space.clip_start = 0.01


def material_viewport(screen):
    """The window's biggest 3D viewport in Material Preview, without overlays, gizmos or a
    selection: (area, space). Fails without one."""
    area = biggest_area(screen, 'VIEW_3D')
    if area is None:
        fail("no 3D viewport")
    space = area.spaces.active
    space.shading.type = 'MATERIAL'
    space.overlay.show_overlays = False
    space.show_gizmo = False
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    return area, space


def window_region(area):
    return next(r for r in area.regions if r.type == 'WINDOW')


def area_move(win, screen, x, y, delta):
    """Move the edge between two editors that passes through (x, y) by delta pixels. The mouse
    must be over no region: move it onto the edge a step before."""
    with bpy.context.temp_override(window=win, screen=screen):
        try:
            bpy.ops.screen.area_move(x=x, y=y, delta=delta)
            return True
        except RuntimeError as e:
            log("could not move an edge: %s" % e)
            return False


def scroll(win, screen, area, down=True, steps=40):
    with bpy.context.temp_override(window=win, screen=screen, area=area, region=window_region(area)):
        for _ in range(steps):
            if down:
                bpy.ops.view2d.scroll_down(deltax=0, deltay=100)
            else:
                bpy.ops.view2d.scroll_up(deltax=0, deltay=100)


def shot(win, screen, area, path):
    """Save a screenshot of `area` (None: the whole window) to path."""
    if area is None:
        with bpy.context.temp_override(window=win, screen=screen, area=biggest_area(screen, 'VIEW_3D')):
            bpy.ops.screen.screenshot(filepath=path, check_existing=False)
    else:
        with bpy.context.temp_override(window=win, screen=screen, area=area, region=window_region(area)):
            bpy.ops.screen.screenshot_area(filepath=path, check_existing=False)
    if not os.path.isfile(path):
        fail("screenshot %s was not written" % path)
    if _black(path):
        _screen_grab(win, area, path)
    log("wrote %s" % path)
    return path


def _black(path):
    """Whether the PNG at path is black all over (Blender 4.x/5.x under Xvfb with Mesa's llvmpipe
    read the window's front buffer as black)."""
    import numpy as np
    image = bpy.data.images.load(path, check_existing=False)
    try:
        px = np.empty(image.size[0] * image.size[1] * image.channels, np.float32)
        image.pixels.foreach_get(px)
        return float(px.reshape(-1, image.channels)[:, :3].max(initial=0.0)) == 0.0
    finally:
        bpy.data.images.remove(image)


def _screen_grab(win, area, path):
    """The X server's picture of the window (xwd, x11-apps) cropped to area, as PNG (netpbm)."""
    import shutil
    import subprocess
    if not (shutil.which("xwd") and shutil.which("xwdtopnm") and shutil.which("pnmtopng")):
        fail("Blender's screenshot %s is black and xwd/netpbm are not there to grab the screen "
             "(Debian: apt install x11-apps netpbm)" % path)
    crop = ""
    if area is not None:  # X's rows count from the top, Blender's from the bottom
        top = win.height - (area.y + area.height)
        crop = " | pnmcut -left %d -top %d -width %d -height %d" % (area.x, top, area.width, area.height)
    cmd = "xwd -root -silent | xwdtopnm 2>/dev/null%s | pnmtopng > '%s'" % (crop, path)
    subprocess.run(["sh", "-c", cmd], check=True)


def run(steps):
    """Run the generator function steps() from a timer in the window, each yield the seconds to wait;
    any error ends Blender with a message."""
    if bpy.app.background:
        fail("run with a window (xvfb-run blender --python ...), not with -b")
    state = {}

    def tick():
        try:
            if "gen" not in state:
                state["gen"] = steps()
            return next(state["gen"])
        except StopIteration:
            return None
        except Exception as e:  # noqa: BLE001
            import traceback
            traceback.print_exc()
            fail("screenshot step failed: %s" % e)

    bpy.app.timers.register(tick, first_interval=2.0)
