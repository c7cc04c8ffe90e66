"""An artist's first bake, in a real Blender window: the artist's room of blend_tests/scenes.py
(Solidify, Boolean, Array, Mirror, Bevel and Subdivision Surface modifiers, smooth shading, an
image texture on the floor) with Blender's default material on the walls, a glass pane in the
window, a sun and a sky texture, baked with the add-on's operator; then shown in Material Preview
with the lightmaps, rendered in EEVEE with the lightmaps and rendered in Cycles without them.

    scripts/blender.sh 5.2 ...   (or 4.3 / 3.4; run under Xvfb with a window:)
    PHOTONLM_SOURCE_DIR=$PWD scripts/in_root.sh /var/cache/photonlm/roots/sid \\
        xvfb-run -a -s "-screen 0 1600x1000x24" blender --factory-startup \\
        --python docs/make_trial_screenshots.py -- OUT_DIR

(with PHOTONLM_LIBRARY set to build/addon_stage/photonlm_blender/lib/photonlm/libphotonlm.so for
the roots' Blenders). Writes into OUT_DIR: trial_viewport.png (Material Preview, lightmaps on),
trial_eevee.png (EEVEE render of the baked lightmaps), trial_cycles.png (Cycles render, lightmaps
off) and trial_panel.png (the window with the PhotonLM panel), and prints the bake's statistics and
reports. With PHOTONLM_DOC_SAVE=1 copies them to docs/images/ with the Blender version in the name.
"""
import math
import os
import shutil
import sys
import time

import bpy
from mathutils import Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import window_shots as ws  # noqa: E402
from window_shots import biggest_area, fail  # noqa: E402

ws.NAME = "make_trial_screenshots"
TARGET = float(os.environ.get("PHOTONLM_DOC_TARGET", 0.02))
SHADER_WAIT = float(os.environ.get("PHOTONLM_DOC_WAIT", 20.0))
SRC = ws.SRC
argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
OUT = os.path.abspath(argv[0]) if argv else "/tmp/trial_shots"
EYE, TARGET_POINT, LENS = (-2.85, -1.5, 1.65), (1.8, 0.5, 0.8), 18.0
RENDER_SIZE = (800, 500)


def version_tag():
    return "%d.%d" % bpy.app.version[:2]


def default_material():
    """A material as Blender's New button makes it (Principled BSDF with its defaults)."""
    mat = bpy.data.materials.new("Material")
    if not getattr(mat, "use_nodes", True) or not mat.node_tree:
        mat.use_nodes = True
    return mat


def glass_pane():
    """An 8 mm Glass BSDF pane filling the window that the walls' Boolean cuts (scenes.artist_room:
    x 3 to 3.2, y -0.8 to 0.8, z 0.9 to 2.1); geometry only (it gets no lightmap)."""
    mat = bpy.data.materials.new("mat_glass")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    glass = nt.nodes.new("ShaderNodeBsdfGlass")
    glass.inputs["IOR"].default_value = 1.5
    nt.links.new(glass.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(3.1, 0.0, 1.5))
    pane = bpy.context.active_object
    pane.name = "Glass"
    pane.scale = (0.008, 1.6, 1.2)
    pane.data.materials.append(mat)
    pane.photonlm.enabled = False
    return pane


def sky_world(sun):
    """A sky texture lit by the sun's direction: Nishita where Blender has it (4.x), its successor
    Single Scattering in 5.x, Hosek-Wilkie in 3.4 builds without Nishita."""
    world = bpy.context.scene.world
    if not getattr(world, "use_nodes", True) or not world.node_tree:
        world.use_nodes = True
    nt = world.node_tree
    sky = nt.nodes.new("ShaderNodeTexSky")
    kinds = [i.identifier for i in sky.bl_rna.properties["sky_type"].enum_items]
    for kind in ("SINGLE_SCATTERING", "NISHITA", "HOSEK_WILKIE"):
        if kind in kinds:
            sky.sky_type = kind
            break
    d = sun.matrix_world.to_3x3() @ Vector((0.0, 0.0, 1.0))
    if hasattr(sky, "sun_elevation"):
        sky.sun_elevation = math.asin(max(min(d.z, 1.0), -1.0))
        sky.sun_rotation = math.atan2(d.y, d.x) - math.pi / 2
        if hasattr(sky, "sun_disc"):
            sky.sun_disc = False
    else:
        sky.sun_direction = d
    bg = nt.nodes["Background"]
    bg.inputs["Strength"].default_value = 0.3
    nt.links.new(sky.outputs[0], bg.inputs["Color"])
    return sky.sky_type


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
    objs = scenes.artist_room(OUT)
    walls = objs.get("Walls")
    if walls is not None:
        walls.data.materials.clear()
        walls.data.materials.append(default_material())
    sun = next(o for o in bpy.context.scene.objects if o.type == 'LIGHT' and o.data.type == 'SUN')
    sky = sky_world(sun)
    glass_pane()
    ws.log("Blender %s, sky %s, walls with Blender's default material, a glass pane in the window"
           % (bpy.app.version_string, sky))
    s = bpy.context.scene.photonlm
    s.output_dir = os.path.join(OUT, "lightmaps")
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
    ws.log("baked %d objects, %s photons in %.1f s (wall %.1f s), error %.3f"
           % (len(last["objects"]), "{:,}".format(int(last["stats"]["photons_emitted"])),
              last["stats"]["seconds_total"], time.perf_counter() - t0, last["stats"]["error_estimate"]))
    for level, text in last["reports"]:
        ws.log("report %s: %s" % (level, text))


def camera():
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    bpy.context.scene.collection.objects.link(cam)
    eye, target = Vector(EYE), Vector(TARGET_POINT)
    cam.location = eye
    cam.rotation_euler = (target - eye).to_track_quat('-Z', 'Y').to_euler()
    cam.data.lens = LENS
    cam.data.clip_start = 0.01
    bpy.context.scene.camera = cam


def render(engine, path, samples):
    from photonlm_blender import compat
    scene = bpy.context.scene
    scene.render.engine = compat.eevee_engine_id() if engine == "EEVEE" else 'CYCLES'
    scene.render.resolution_x, scene.render.resolution_y = RENDER_SIZE
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = 'PNG'
    scene.view_settings.view_transform = 'Standard'
    if engine == "CYCLES":
        scene.cycles.samples = samples
        scene.cycles.device = 'CPU'
    scene.render.filepath = path
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    ws.log("%s render %.1f s: %s" % (engine, time.perf_counter() - t0, path))


def save(name):
    path = os.path.join(OUT, name + ".png")
    if os.environ.get("PHOTONLM_DOC_SAVE"):
        dst = os.path.join(SRC, "docs", "images", "%s_%s.png" % (name, version_tag()))
        shutil.copyfile(path, dst)
        ws.log("wrote %s" % dst)
    return path


def steps():
    win = bpy.context.window_manager.windows[0]
    screen = win.screen
    area, space = ws.material_viewport(screen)
    ws.look(space, EYE, TARGET_POINT, LENS)
    props = next((a for a in screen.areas if a.type == 'PROPERTIES'), None)
    if props is not None:
        props.spaces.active.context = 'RENDER'
    bpy.context.scene.photonlm.preview = True
    yield SHADER_WAIT
    ws.shot(win, screen, None, os.path.join(OUT, "trial_panel.png"))
    save("trial_panel")
    with bpy.context.temp_override(window=win, screen=screen, area=area):
        bpy.ops.screen.screen_full_area()
    yield 2.0
    screen = win.screen
    area = biggest_area(screen, 'VIEW_3D')
    area.spaces.active.show_region_header = False
    area.spaces.active.show_region_toolbar = False
    yield SHADER_WAIT / 2
    ws.shot(win, screen, area, os.path.join(OUT, "trial_viewport.png"))
    save("trial_viewport")
    camera()
    render("EEVEE", os.path.join(OUT, "trial_eevee.png"), 0)
    save("trial_eevee")
    bpy.context.scene.photonlm.preview = False
    render("CYCLES", os.path.join(OUT, "trial_cycles.png"), int(os.environ.get("PHOTONLM_DOC_SAMPLES", 32)))
    save("trial_cycles")
    yield 0.5
    bpy.ops.wm.quit_blender()


def main():
    bpy.context.preferences.view.show_splash = False
    setup()
    ws.run(steps)


main()
