"""The Blender half of the web viewer's test (web/test/test_web_viewer.py) and of
docs/make_web_screenshots.py: a scene baked with the add-on, exported with its lightmaps to a .glb
(File > Export > glTF with PhotonLM lightmaps), and rendered in EEVEE with the lightmap preview
under the Standard view transform, the view the page must reproduce.

    scripts/blender.sh 5.2 -b --factory-startup --python-exit-code 1 \\
        --python blend_tests/web_viewer_scene.py -- OUT_DIR [cornell|room|groups|artist|bricks] [WIDTH HEIGHT [PHOTONS]]

Scenes: `cornell`, the Cornell box (32 x 32 texels per object); `room`, the sunlit room of
scenes.light_groups_room without its light groups (64 x 64); `groups`, that room with its light
groups (sun and sky "day", two lamps "night", 32 x 32), mixed as GROUPS_MIX says before the
export and the render (the file carries the mix; the page mixes the layers as the preview does);
`artist`, the artist's room (scenes.artist_room: Blender's default materials, a modifier stack, an
image texture, smooth shading, a sun through a Boolean window) from inside; `bricks`, the brick wall of
blend_tests/test_directional.py (a normal map of bevelled bricks, a sun 55 degrees from its normal and
a sky) baked with Directional: the page evaluates the SH bands at the normal map's normals as the
preview does. Their Diffuse BSDFs are swapped for
Principled BSDFs of the same colour (no specular, roughness 1), which Blender's glTF exporter
writes as base colours. Writes into OUT_DIR:
- scene.glb, the export;
- blender.png, the EEVEE render (WIDTH x HEIGHT, default 320 x 240; Standard, no dither, black world);
- view.json, the render's camera in glTF's axes for the page's URL (cam, target, vertical fov in
  degrees, width, height) and the export's numbers (seconds, file size, each lightmap's texels
  and PNG bytes).
"""
import json
import math
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
from mathutils import Vector  # noqa: E402


def look_from(eye, target, lens):
    """The scene's camera at `eye` looking at `target` (lens in mm, a 36 mm sensor fitted automatically)."""
    data = bpy.data.cameras.new("camera")
    data.lens, data.sensor_width, data.sensor_fit = lens, 36.0, 'AUTO'
    cam = bpy.data.objects.new("camera", data)
    bpy.context.scene.collection.objects.link(cam)
    cam.location = eye
    cam.rotation_euler = (Vector(target) - Vector(eye)).to_track_quat('-Z', 'Y').to_euler()
    bpy.context.scene.camera = cam


def build(kind):
    """The scene to bake and its camera; returns (bake settings)."""
    if kind == "cornell":
        scenes.clear_scene()
        scenes.cornell_box(resolution=32)
        scenes.cornell_camera()
        bake = dict(max_bounces=8, target_error=0.01)
    elif kind == "room":
        scene, sun, lamp, panel = scenes.light_groups_room(64, (0.45, 0.6, 1.0))
        for light in (lamp, panel):  # the day: sun and sky, no light groups
            bpy.data.objects.remove(light)
        sun.lightgroup = scene.world.lightgroup = ""
        vl = bpy.context.view_layer
        while len(vl.lightgroups):
            vl.lightgroups.remove(vl.lightgroups[0])
        bake = dict(max_bounces=8, target_error=0.01, direct_samples=16)
    elif kind == "artist":
        scenes.clear_scene()
        scenes.artist_room(scenes.out_dir("web_viewer_artist"))
        look_from((-2.85, -1.5, 1.65), (1.8, 0.5, 0.8), 18.0)
        bake = dict(max_bounces=8, target_error=0.01)
    elif kind == "bricks":
        scenes.clear_scene()
        normals = scenes.brick_normals(96)
        scenes.brick_wall(96, scenes.brick_material("mat_wall", scenes.normal_map_image("bricks_normal", normals)))
        scenes.add_sun(scenes.BRICK_SUN, 3.0)
        scenes.set_world_color(scenes.BRICK_SKY, 1.0)
        look_from((0.3, -3.2, 1.2), (0.0, 0.0, 1.0), 35.0)
        bake = dict(max_bounces=4, target_error=0.0, directional=True, direct_samples=64, photons=1_000_000)
    elif kind == "groups":
        scenes.light_groups_room(32, (0.45, 0.6, 1.0))
        bake = dict(max_bounces=8, target_error=0.01, direct_samples=16)
    else:
        raise SystemExit("web_viewer_scene: unknown scene '%s' (cornell, room, groups, artist or bricks)" % kind)
    scenes.principled_materials()
    return bake


GROUPS_MIX = {"day": (1.0, (1.0, 1.0, 1.0)), "night": (0.4, (1.0, 0.7, 0.4))}  # strength, tint


def set_mix():
    """The Light Groups panel's strengths and tints as GROUPS_MIX says."""
    groups = bpy.context.scene.photonlm.light_groups
    for name, (strength, tint) in GROUPS_MIX.items():
        groups[name].strength = strength
        groups[name].tint = tint
    bpy.context.view_layer.update()


def camera_view(width, height):
    """The scene camera in glTF's axes (Blender (x, y, z) is (x, z, -y)): position, a point on its
    axis and the vertical field of view of a width x height render (sensor fit Auto)."""
    cam = bpy.context.scene.camera
    data = cam.data
    if data.sensor_fit not in ('AUTO', 'HORIZONTAL') or data.shift_x or data.shift_y:
        raise SystemExit("web_viewer_scene: the camera must fit its sensor horizontally, without shift")
    m = cam.matrix_world
    pos = m.translation
    forward = (m.to_3x3() @ Vector((0.0, 0.0, -1.0))).normalized()
    half = math.atan(data.sensor_width / (2.0 * data.lens))  # along the larger side
    if width >= height or data.sensor_fit == 'HORIZONTAL':
        half_v = math.atan(math.tan(half) * height / width)
    else:
        half_v = half

    def gltf(v):
        return [round(v[0], 6), round(v[2], 6), round(-v[1], 6)]
    return dict(cam=gltf(pos), target=gltf(pos + forward), fov=math.degrees(2.0 * half_v), width=width, height=height)


def render(path, width, height):
    """The lightmap preview (scenes.render_lightmap_preview) as an 8-bit PNG, no dither."""
    r = bpy.context.scene.render
    r.dither_intensity = 0.0
    r.image_settings.file_format = 'PNG'
    r.image_settings.color_mode = 'RGB'
    r.image_settings.color_depth = '8'
    scenes.render_lightmap_preview(path, width, height)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if not argv:
        raise SystemExit("usage: ... --python blend_tests/web_viewer_scene.py -- OUT_DIR [cornell|room] "
                         "[WIDTH HEIGHT [PHOTONS]]")
    out = os.path.abspath(argv[0])
    kind = argv[1] if len(argv) > 1 else "cornell"
    width, height = (int(argv[2]), int(argv[3])) if len(argv) > 3 else (320, 240)
    photons = int(argv[4]) if len(argv) > 4 else 20_000_000
    os.makedirs(out, exist_ok=True)
    scenes.enable_gltf_addons()
    bake = build(kind)
    bpy.context.scene.photonlm.output_dir = os.path.join(out, "lightmaps")
    last = scenes.photonlm_bake(bake.pop("photons", photons), seed=1, **bake)
    print("web_viewer_scene: baked %d objects in %.1f s" % (len(last["objects"]), last["wall_seconds"]), flush=True)

    if kind == "groups":
        set_mix()
    from photonlm_blender.gltf.export import export_glb
    glb = os.path.join(out, "scene.glb")
    t0 = time.perf_counter()
    summary = export_glb(bpy.context, glb)
    seconds = time.perf_counter() - t0
    lightmaps = {}
    for name, tex in summary["textures"].items():
        image = bpy.data.images.get(name)  # the SH bands' textures have no image of that name
        if image is None:
            continue
        w, h = image.size
        lightmaps[name] = dict(texels=w * h, png_bytes=tex["png_bytes"], range=tex["range"])
    render(os.path.join(out, "blender.png"), width, height)
    view = camera_view(width, height)
    view.update(scene=kind, blender=bpy.app.version_string, export_seconds=seconds, glb_bytes=summary["size"],
                lightmaps=lightmaps, bake_seconds=last["wall_seconds"])
    with open(os.path.join(out, "view.json"), "w") as f:
        json.dump(view, f, indent=1)
    texels = sum(v["texels"] for v in lightmaps.values())
    png = sum(v["png_bytes"] for v in lightmaps.values())
    print("web_viewer_scene: %s exported in %.2f s, %d bytes; %d lightmaps, %d texels in %d PNG bytes "
          "(%.2f MB per million texels)" % (glb, seconds, summary["size"], len(lightmaps), texels, png,
                                            png / texels), flush=True)


main()
