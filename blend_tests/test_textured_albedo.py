"""Textured albedo: colour bleeding from a checkerboard-textured wall onto a white wall, photonlm
vs a converged Cycles bake.

Scene: a 2 m checker wall (plane x = 0, facing +x; Diffuse BSDF whose Color is an Image Texture
of a saturated red / green 2 x 2 checker (1 m cells), created in memory here, on the mesh's UV map 'UVMap'
through a UV Map node) and a 2 m white wall (plane y = 0, facing +y, albedo 0.8) meeting it at a
right angle. A narrow spot light aims at the checker wall and does not reach the white wall, so
all the white wall receives is light reflected by the checker: red where red cells face it, green
where green cells do.

photonlm: bpy.ops.photonlm.bake(), all bounces. Cycles: DIFFUSE, DIRECT + INDIRECT, no COLOR,
32 bounces, no clamp. Two bakes of each (different seeds): the means are compared on the white
wall (32 x 32), the differences give the noise. Per channel: RMSE / mean(Cycles) below 1.25 x the
noise + 2 %, channel means within 1 %;
and the red fraction r / (r + g) per texel (the bleeding's pattern). A bake with the checker
replaced by its plain average colour (0.5, 0.5, 0) must be clearly worse (so the test can fail).
"""
import math
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

RES = 32
PHOTONS = int(os.environ.get("PHOTONLM_TEST_PHOTONS", 8_000_000))
CYCLES_SAMPLES = int(os.environ.get("PHOTONLM_TEST_CYCLES_SAMPLES", 4096))
TOLERANCE = 0.02         # per channel RMSE / mean(Cycles) allowed beyond 1.25 x the measured noise
RATIO_LIMIT = 0.03       # RMS difference of r / (r + g) over well-lit texels
WORSE_FACTOR = 2.0       # the untextured stand-in must be at least this much further off


def checker_image(n=64, cells=2):
    img = bpy.data.images.new("checker", n, n, alpha=True)  # byte, sRGB: 0 and 1 are exact
    y, x = np.mgrid[0:n, 0:n]
    red = ((x * cells // n + y * cells // n) % 2) == 0
    px = np.zeros((n, n, 4), np.float32)
    px[red, 0] = 1.0
    px[~red, 1] = 1.0
    px[..., 3] = 1.0
    img.pixels.foreach_set(px.ravel())
    return img


def textured_material(image):
    mat = scenes.diffuse_material("checker", (0.5, 0.5, 0.0))
    nt = mat.node_tree
    bsdf = next(n for n in nt.nodes if n.bl_idname == 'ShaderNodeBsdfDiffuse')
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.interpolation = 'Linear'
    uvn = nt.nodes.new("ShaderNodeUVMap")
    uvn.uv_map = "UVMap"
    nt.links.new(uvn.outputs["UV"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Color"])
    return mat


def build():
    scenes.clear_scene()
    image = checker_image()
    checker_mat = textured_material(image)
    white = scenes.diffuse_material("white", (0.8, 0.8, 0.8))
    # Checker wall: x = 0, y in [0, 2], z in [0, 2], normal +x (p1 - p0 = +y, p3 - p0 = +z).
    checker = scenes.quads_object("checker_wall", [((0, 0, 0), (0, 2, 0), (0, 2, 2), (0, 0, 2), (0, 0, 1, 1))],
                                  checker_mat, RES)
    # White wall: y = 0, x in [0, 2], z in [0, 2], normal +y (p1 - p0 = +z, p3 - p0 = +x).
    wall = scenes.quads_object("white_wall", [((0, 0, 0), (0, 0, 2), (2, 0, 2), (2, 0, 0), (0, 0, 1, 1))],
                               white, RES)
    # Spot at x = 1.8 aiming along -x at the checker wall; its 45 degree cone misses the white wall
    # (seen from the spot, the white wall is at least 29 degrees off the axis).
    scenes.add_light("spot", 'SPOT', (1.8, 1.0, 1.0), rotation=(0, math.radians(90), 0),
                     energy=300.0, shadow_soft_size=0.05, spot_size=math.radians(45), spot_blend=0.0)
    return checker, wall, checker_mat, image


def export_checks(checks, image):
    """What materials.py makes of other node set-ups (no bake)."""
    from photonlm_blender import bridge
    from photonlm_blender.export import materials
    photonlm = bridge.get()
    mat = scenes.diffuse_material("principled_tex", (0.8, 0.8, 0.8), principled=True)
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    bsdf.inputs["Metallic"].default_value = 0.25
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = image
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    nt.links.new(tex.outputs["Color"], scenes.principled_input(bsdf, "Emission"))
    bsdf.inputs["Emission Strength"].default_value = 3.0
    info = materials.read_material(mat)
    checks.check(info.albedo_texture is not None and info.albedo_texture.uv_map is None
                 and info.albedo == (0.75, 0.75, 0.75), "Principled: Image -> Base Color is a texture on the "
                 "render UV map, albedo factor 1 - Metallic = %s" % (info.albedo,))
    checks.check(info.emission_texture is not None and info.emission == (3.0, 3.0, 3.0),
                 "Principled: Image -> Emission is an emission texture x strength %s" % (info.emission,))
    # A Mapping node on the coordinates: still the image, on the render UV map, reported.
    mapping = nt.nodes.new("ShaderNodeMapping")
    nt.links.new(mapping.outputs[0], tex.inputs["Vector"])
    info = materials.read_material(mat)
    checks.check(info.albedo_texture is not None and any("only a UV Map node" in n for n in info.notes),
                 "Mapping node on the Vector input is reported: %s" % info.notes[:1])
    # A procedural texture: the grey fallback, reported.
    noise = nt.nodes.new("ShaderNodeTexNoise")
    nt.links.new(noise.outputs["Color"], bsdf.inputs["Base Color"])
    info = materials.read_material(mat)
    checks.check(info.albedo_texture is None
                 and np.allclose(info.albedo, [0.75 * c for c in materials.FALLBACK_ALBEDO], atol=1e-6)
                 and any("not an Image Texture" in n for n in info.notes),
                 "procedural Base Color falls back to grey 0.8 (x 1 - Metallic) with a note: %s" % info.notes[:1])
    # Images for the engine: generated -> a temporary PPM; saved to a PNG -> that file, sRGB.
    files = materials.TextureFiles()
    path, space = files.path_of(image)
    checks.check(path.endswith(".ppm") and os.path.isfile(path) and space == "srgb",
                 "generated image written to %s (%s)" % (path, space))
    png = os.path.join(scenes.out_dir("textured_albedo"), "checker.png")
    saved = image.copy()
    saved.filepath_raw = png
    saved.file_format = 'PNG'
    saved.save()
    loaded = bpy.data.images.load(png)
    path2, space2 = files.path_of(loaded)
    checks.check(os.path.samefile(path2, png) and space2 == "srgb", "file image used in place: %s (%s)"
                 % (path2, space2))
    # A file type the engine does not decode (TIFF): Blender's pixels go to the engine instead.
    tif = os.path.join(scenes.out_dir("textured_albedo"), "checker.tif")
    saved.filepath_raw = tif
    saved.file_format = 'TIFF'
    saved.save()
    tiff_image = bpy.data.images.load(tif)
    path3, space3 = files.path_of(tiff_image)
    scene = photonlm.Scene()
    mid = scene.add_material((1, 1, 1))
    try:
        scene.set_material_texture(mid, "albedo", path3, space3)
        accepted = True
    except Exception as e:  # noqa: BLE001
        accepted = e
    try:
        scene.set_material_texture(mid, "albedo", tif, "srgb")
        refused = "not refused"
    except Exception as e:  # noqa: BLE001
        refused = str(e)
    scene.close()
    checks.check("PNG" in refused and "checker.tif" in refused,
                 "the engine itself refuses the TIFF, naming the types it reads: %s" % refused)
    checks.check(path3.endswith(".ppm") and accepted is True and space3 == "srgb",
                 "a TIFF image is handed over as its pixels (%s, %s), which the engine reads: %s"
                 % (path3, space3, accepted))
    files.cleanup()
    checks.check(not os.path.exists(path), "cleanup removes the temporary image")
    bpy.data.materials.remove(mat)


def red_fraction(rgb):
    return rgb[..., 0] / np.maximum(rgb[..., 0] + rgb[..., 1], 1e-30)


def temporary_image_dirs():
    import glob
    import tempfile
    return glob.glob(os.path.join(tempfile.gettempdir(), "photonlm-images-*"))


def main():
    import shutil
    import tempfile
    scenes.setup_paths()
    checks = scenes.Checks("textured_albedo")
    # A private temporary folder: tests running beside this one make their own image folders.
    tempfile.tempdir = tempfile.mkdtemp(prefix="photonlm-test-textured-")
    before = set(temporary_image_dirs())
    checker, wall, checker_mat, image = build()
    bpy.context.view_layer.update()

    # The export reads the Image Texture (not the grey fallback) on the UV Map node's map.
    from photonlm_blender.export import materials
    info = materials.read_material(checker_mat)
    checks.check(info.albedo_texture is not None and info.albedo_texture.uv_map == "UVMap"
                 and info.albedo == (1.0, 1.0, 1.0), "export: Image Texture -> Color becomes an albedo texture "
                 "on 'UVMap' (notes: %s)" % info.notes)

    export_checks(checks, image)

    # Two independent bakes each: their mean is compared, their difference measures the noise.
    refs, t_cycles = [], 0.0
    for seed in (0, 1):
        r, t = scenes.cycles_bake([wall], RES, {'DIRECT', 'INDIRECT'}, CYCLES_SAMPLES, bounces=32, seed=seed)
        refs.append(r["white_wall"])
        t_cycles += t
    runs = []
    for seed in (7, 8):
        last = scenes.photonlm_bake(PHOTONS, 1024, seed=seed, target_error=0.0)
        runs.append(last["objects"]["white_wall"]["rgb"])
        st = last["stats"]
        print("photonlm %.2f s (%d photons, export %.3f s)" % (st["seconds_total"], st["photons_emitted"],
                                                              st["seconds_export"]))
    print("Cycles %.2f s for 2 x %d samples" % (t_cycles, CYCLES_SAMPLES))
    ref, ours = (refs[0] + refs[1]) / 2, (runs[0] + runs[1]) / 2
    texture_warnings = [w for w in last.get("warnings", []) if "texture" in str(w).lower()]
    checks.check(not texture_warnings, "no texture warnings (%s)" % texture_warnings)

    # Untextured stand-in: the checker's plain average colour (linear (0.5, 0.5, 0)).
    flat = scenes.diffuse_material("checker_average", (0.5, 0.5, 0.0))
    checker.data.materials[0] = flat
    bpy.context.view_layer.update()
    flat_rgb = scenes.photonlm_bake(PHOTONS, 1024, seed=7, target_error=0.0)["objects"]["white_wall"]["rgb"]

    # Texels that receive real light (for the colour ratio; the RMSE uses all texels).
    mean_ref = ref[..., :2].mean(axis=(0, 1))
    lit = ref[..., :2].sum(axis=2) > 0.25 * mean_ref.sum()
    print("white wall mean: ours %s cycles %s untextured %s; lit texels %d"
          % (ours.mean(axis=(0, 1)), ref.mean(axis=(0, 1)), flat_rgb.mean(axis=(0, 1)), int(lit.sum())))
    rmse = {}
    for c, name in ((0, "red"), (1, "green")):
        m = ref[..., c].mean()
        # Expected RMSE of (ours - ref) from noise alone: each mean of two has variance
        # mean((a - b)^2) / 4.
        noise = math.sqrt((np.mean((runs[0][..., c] - runs[1][..., c]) ** 2) +
                           np.mean((refs[0][..., c] - refs[1][..., c]) ** 2)) / 4) / m
        limit = 1.25 * noise + TOLERANCE
        for label, img in (("ours", ours), ("untextured", flat_rgb)):
            rmse[label, c] = float(np.sqrt(np.mean((img[..., c] - ref[..., c]) ** 2)) / m)
        checks.check(rmse["ours", c] < limit, "%s channel: RMSE / mean vs Cycles %.4f (noise %.4f; limit 1.25 x "
                     "noise + %.2f = %.4f)" % (name, rmse["ours", c], noise, TOLERANCE, limit))
        checks.check(rmse["untextured", c] > WORSE_FACTOR * rmse["ours", c],
                     "%s channel: the untextured average is worse: %.3f > %.1f x %.3f"
                     % (name, rmse["untextured", c], WORSE_FACTOR, rmse["ours", c]))
        checks.check(abs(ours[..., c].mean() / m - 1) < 0.01, "%s channel mean ours %.4f cycles %.4f (limit 1 %%)"
                     % (name, ours[..., c].mean(), m))
    fr_ref, fr_ours, fr_flat = red_fraction(ref)[lit], red_fraction(ours)[lit], red_fraction(flat_rgb)[lit]
    d_ours = float(np.sqrt(np.mean((fr_ours - fr_ref) ** 2)))
    d_flat = float(np.sqrt(np.mean((fr_flat - fr_ref) ** 2)))
    checks.check(fr_ref.std() > 0.05, "Cycles' bleeding is structured: std of r / (r + g) = %.3f" % fr_ref.std())
    checks.check(d_ours < RATIO_LIMIT, "red fraction r / (r + g): RMS difference %.4f (limit %.2f)"
                 % (d_ours, RATIO_LIMIT))
    checks.check(d_flat > WORSE_FACTOR * d_ours, "red fraction of the untextured average is off: %.4f > %.1f x "
                 "%.4f" % (d_flat, WORSE_FACTOR, d_ours))
    # The temporary image files this test's bakes made are gone.
    left = sorted(set(temporary_image_dirs()) - before)
    checks.check(not left, "temporary texture files removed (%s)" % left)
    shutil.rmtree(tempfile.tempdir, ignore_errors=True)
    np.save(os.path.join(scenes.out_dir("textured_albedo"), "white_wall.npy"), np.stack([ours, ref, flat_rgb, runs[0], runs[1], refs[0], refs[1]]))
    checks.finish()


main()
