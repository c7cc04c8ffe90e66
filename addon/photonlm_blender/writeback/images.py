"""The files and images a write-back makes: the lightmap folder, heat maps and loading images.

Next to each <object>_lightmap.exr the write-back writes <object>_error.exr: the texels'
relative error (standard error / value; 0 where the texel has no light) in R, G and B, loaded as
the image <object>_error for the heat-map preview. Heat-map images larger than ERROR_IMAGE_MAX
per side hold the RMS of blocks of texels.
"""
import atexit
import os
import shutil
import tempfile

import bpy
import numpy as np

from .. import bridge

# Heat-map images larger than this per side hold the RMS of blocks of texels.
ERROR_IMAGE_MAX = 2048

_SESSION_FOLDER = []  # this Blender process's own folder for the lightmaps of unsaved files


def _session_folder():
    """A folder no other project or Blender shares, removed when Blender exits."""
    if not _SESSION_FOLDER or not os.path.isdir(_SESSION_FOLDER[0]):
        _SESSION_FOLDER[:] = [tempfile.mkdtemp(prefix="photonlm-unsaved-")]
        atexit.register(shutil.rmtree, _SESSION_FOLDER[0], True)
    return _SESSION_FOLDER[0]


def is_temporary_output(scene):
    """True where the lightmap files are temporary (a relative folder in an unsaved file): the
    images are then packed into the .blend, which is the only place they last."""
    path = scene.photonlm.output_dir or "//lightmaps/"
    return path.startswith("//") and not bpy.data.is_saved and not os.environ.get("PHOTONLM_TEST_OUT")


def output_directory(scene):
    """The absolute output folder for lightmaps, created if needed.

    A relative (//) path is relative to the .blend file; for an unsaved file it is relative to
    $PHOTONLM_TEST_OUT if set, else to a folder of this Blender process's own (removed when it
    exits; the images are packed, see is_temporary_output).
    """
    path = scene.photonlm.output_dir or "//lightmaps/"
    if path.startswith("//") and not bpy.data.is_saved:
        base = os.environ.get("PHOTONLM_TEST_OUT") or _session_folder()
        path = os.path.join(base, path[2:])
    else:
        path = bpy.path.abspath(path)
    path = os.path.normpath(path)
    os.makedirs(path, exist_ok=True)
    return path


def relative_error(rgb, error):
    """Per-texel relative error: standard error / mean RGB value, 0 where the value is not above 0
    (a texel without light: the engine counts it as below any threshold); at most 65504, the largest
    half float of the heat-map files (a texel holding only rounding residue, inside another object,
    may have an error 10^40 times its value)."""
    value = rgb.sum(axis=2, dtype=np.float32) / np.float32(3.0)
    out = np.zeros(value.shape, np.float32)
    with np.errstate(over='ignore'):
        np.divide(error, value, out=out, where=value > 0.0)
    return np.minimum(out, np.float32(65504.0), out=out)


def error_image_pixels(relative):
    """The heat-map image of an object: its relative errors, or for a lightmap wider than
    ERROR_IMAGE_MAX the root mean square over blocks of k x k texels (k a power of two)."""
    h, w = relative.shape
    k = 1
    while max(h, w) > ERROR_IMAGE_MAX * k and h % (2 * k) == 0 and w % (2 * k) == 0:
        k *= 2
    if k == 1:
        return relative
    r2 = relative.astype(np.float64) ** 2
    return np.sqrt(r2.reshape(h // k, k, w // k, k).mean(axis=(1, 3))).astype(np.float32)


def write_error_exr(path, relative):
    """Write a (h, w) float32 array (row 0 = bottom) into R, G and B of an EXR of 16-bit floats (ZIP),
    atomically, with the engine's writer (no bpy: it may run on a thread). Half floats keep 3
    significant digits: plenty for a heat map, a tenth of the size."""
    bridge.get().write_heat_map_exr(path, relative)


def load_image(name, path, pack=False):
    """Load (or reload) the float image `name` from `path`, colour space Non-Color. The image links
    its file relative to the .blend where the file is saved (the project folder can move), or is
    packed into the .blend (pack)."""
    image = bpy.data.images.get(name)
    if image is not None and image.source == 'FILE':
        if image.packed_file is not None:
            image.unpack(method='REMOVE')  # the new file replaces the packed copy
        image.filepath = path
        image.reload()
    else:
        if image is not None:
            image.name = name + ".old"  # generated: keep it, but free the name
        image = bpy.data.images.load(path, check_existing=False)
        image.name = name
    if bpy.data.is_saved:
        try:
            image.filepath = bpy.path.relpath(path)
        except ValueError:  # another drive than the .blend
            pass
    image.colorspace_settings.name = 'Non-Color'
    if hasattr(image, "use_half_precision"):
        image.use_half_precision = False
    image.alpha_mode = 'NONE'
    if pack:
        image.pack()
    return image
