"""Lightmaps travel with the .blend: a saved project links its lightmap files relative to the
.blend, so the folder can be moved or renamed; an unsaved file packs them (and never writes into a
folder shared with other projects); Pack Lightmaps packs them into a saved one.

Expected:
- saved file, default output //lightmaps/: every image links "//lightmaps/<object>_lightmap.exr";
  after saving, moving the whole project folder and opening the moved .blend, every image has the
  pixels it had after the bake (bit for bit: the EXR is read again).
- unsaved file: the images are packed, their files lie in a folder of this Blender process's own
  (not under the shared temporary folder's photonlm/), and after saving, the packed pixels
  round-trip through the .blend unchanged.
- Pack Lightmaps on a saved file: packed; the moved .blend keeps the pixels with the lightmaps
  folder deleted.
All of it once with a lightmap per object and once with atlases (the pages are the images then;
the objects' photonlm_atlas_file and the scene's atlas layout link the pages relative to the .blend).
"""
import os
import shutil
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402


def build_scene(layout):
    scenes.clear_scene()
    scenes.cornell_box(resolution=16)
    bpy.context.scene.photonlm.lightmap_layout = layout
    bpy.context.scene.photonlm.atlas_size = '512'


def lightmap_pixels():
    """Pixels of every lightmap image (name -> float array), read from the image itself."""
    out = {}
    for image in bpy.data.images:
        if image.name.endswith("_lightmap"):
            px = np.empty(len(image.pixels), np.float32)
            image.pixels.foreach_get(px)
            out[image.name] = px
    return out


def same_pixels(checks, before, what):
    after = lightmap_pixels()
    checks.check(sorted(after) == sorted(before) and len(before) > 0,
                 "%s: the same %d lightmap images (%s)" % (what, len(before), ", ".join(sorted(after))))
    for name, px in before.items():
        got = after.get(name)
        checks.check(got is not None and got.shape == px.shape and np.array_equal(got, px)
                     and float(px.max()) > 0.0,
                     "%s: %s has its pixels (max %.4g)" % (what, name, float(px.max())))


def main():
    checks = scenes.Checks("lightmaps_travel")
    scenes.setup_paths()
    os.environ.pop("PHOTONLM_TEST_OUT", None)  # the user's set-up: no test folder
    for layout in ('OBJECT', 'ATLAS'):
        bpy.ops.wm.read_homefile(use_empty=True)
        scenes.setup_paths()
        run(checks, layout)
    checks.finish()


def run(checks, layout):
    from photonlm_blender.writeback import images as image_files
    root = tempfile.mkdtemp(prefix="photonlm-travel-")
    try:
        # -- a saved project, files linked relative to it --------------------------------------
        build_scene(layout)
        project = os.path.join(root, "project")
        os.makedirs(project)
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(project, "room.blend"))
        scenes.setup_paths()
        scenes.photonlm_bake(200_000, 8, target_error=0.0)
        links = {im.name: im.filepath for im in bpy.data.images if im.name.endswith("_lightmap")}
        checks.check(links and all(p.startswith("//lightmaps/") and p.endswith("_lightmap.exr") for p in links.values()),
                     "images link their files relative to the .blend: %s" % sorted(links.values()))
        checks.check(all(im.packed_file is None for im in bpy.data.images if im.name.endswith("_lightmap")),
                     "a saved file does not pack by default")
        if layout == 'ATLAS':
            atlas = bpy.context.scene.get("photonlm_atlas")
            files = list(atlas["files"]) if atlas else []
            checks.check(len(links) == len(files) >= 1 and all(f.startswith("//lightmaps/") for f in files)
                         and all(o.get("photonlm_atlas_file") in files for o in bpy.data.objects
                                 if o.type == 'MESH'),
                         "atlas pages %s and the objects' photonlm_atlas_file are relative to the .blend" % files)
        before = lightmap_pixels()
        bpy.ops.wm.save_mainfile()
        moved = os.path.join(root, "moved project")
        shutil.move(project, moved)
        bpy.ops.wm.open_mainfile(filepath=os.path.join(moved, "room.blend"))
        same_pixels(checks, before, "moved folder")

        # -- Pack Lightmaps on a saved file -------------------------------------------------------
        scenes.setup_paths()
        bpy.context.scene.photonlm.pack_lightmaps = True
        scenes.photonlm_bake(200_000, 8, seed=2, target_error=0.0)
        checks.check(all(im.packed_file is not None for im in bpy.data.images if im.name.endswith("_lightmap")),
                     "Pack Lightmaps packs the images")
        before = lightmap_pixels()
        bpy.ops.wm.save_mainfile()
        again = os.path.join(root, "moved again")
        shutil.move(moved, again)
        shutil.rmtree(os.path.join(again, "lightmaps"))
        bpy.ops.wm.open_mainfile(filepath=os.path.join(again, "room.blend"))
        same_pixels(checks, before, "packed, lightmaps folder deleted")

        # -- an unsaved file packs, in a folder of its own ----------------------------------------
        bpy.ops.wm.read_homefile(use_empty=True)
        scenes.setup_paths()
        build_scene(layout)
        checks.check(not bpy.data.is_saved, "the file is unsaved")
        folder = image_files.output_directory(bpy.context.scene)
        shared = os.path.join(tempfile.gettempdir(), "photonlm")
        checks.check(not os.path.normpath(folder).startswith(shared + os.sep) and os.path.isdir(folder),
                     "an unsaved file writes into a folder of its own (%s), not %s" % (folder, shared))
        scenes.photonlm_bake(200_000, 8, seed=3, target_error=0.0)
        images = [im for im in bpy.data.images if im.name.endswith("_lightmap")]
        checks.check(images and all(im.packed_file is not None for im in images),
                     "an unsaved file packs its %d lightmaps" % len(images))
        before = lightmap_pixels()
        path = os.path.join(root, "first save", "new.blend")
        os.makedirs(os.path.dirname(path))
        bpy.ops.wm.save_as_mainfile(filepath=path)
        bpy.ops.wm.open_mainfile(filepath=path)
        same_pixels(checks, before, "packed in an unsaved file, then saved")
    finally:
        shutil.rmtree(root, ignore_errors=True)


main()
