"""A .glb with lightmaps (docs/gltf.md) brought back into Blender: Blender's glTF importer makes the
objects, and each material whose extras hold `photonlm_lightmap` (the importer keeps them as the
material's custom property) gets its lightmap again, wired as a bake wires it.

    summary = import_glb(context, filepath)

The importer loads no lightmap: MOZ_lightmap and FB_materials_lightmap are not in its reach. So the
file is read here too (GLB header, JSON and BIN chunks): each lightmap texture's PNG is decoded from
RGBM (rgbm.py) into a float image named as in the extras' `image` (an atlas page once for all its
objects; numbered by Blender where the name is taken), packed into the .blend, and read through the object's UV map of the extras' `texCoord`
(the importer gives TEXCOORD_1 as the mesh's second UV map). Light-group layers are not rewired: the
lightmap is their sum.
"""
import json
import os
import struct
import tempfile
import time

import bpy
import numpy as np

from ..writeback import wiring
from . import rgbm
from .export import EXTRAS_KEY, ExportError


def read_glb(path):
    """(JSON dict, BIN bytes) of a .glb; ExportError naming the file when it is not one."""
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < 20 or data[:4] != b"glTF":
        raise ExportError("%s is not a binary glTF (.glb)" % path)
    n, kind = struct.unpack_from("<I4s", data, 12)
    if kind != b"JSON":
        raise ExportError("%s: the first chunk is not JSON" % path)
    doc = json.loads(data[20:20 + n])
    binary = b""
    if len(data) >= 28 + n:
        m, kind = struct.unpack_from("<I4s", data, 20 + n)
        if kind == b"BIN\0":
            binary = data[28 + n:28 + n + m]
    return doc, binary


def png_bytes(doc, binary, texture):
    image = doc["images"][doc["textures"][texture]["source"]]
    if "bufferView" not in image:
        raise ExportError("lightmap texture %d is not inside the file" % texture)
    v = doc["bufferViews"][image["bufferView"]]
    return binary[v.get("byteOffset", 0):v.get("byteOffset", 0) + v["byteLength"]]


def png_rgba(data):
    """An 8-bit PNG's bytes as Blender reads them: (h, w, 4) uint8, row 0 = bottom."""
    fd, path = tempfile.mkstemp(suffix=".png")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        png = bpy.data.images.load(path, check_existing=False)
        try:
            png.colorspace_settings.name = 'Non-Color'
            w, h = png.size
            px = np.empty(w * h * 4, np.float32)
            png.pixels.foreach_get(px)
        finally:
            bpy.data.images.remove(png)
    finally:
        os.remove(path)
    return np.rint(px.reshape(h, w, 4) * 255.0).astype(np.uint8)


def decoded_image(name, data, value_range):
    """A packed float image `name` holding the RGBM PNG `data` decoded (linear; row 0 = bottom)."""
    value = rgbm.decode(png_rgba(data), value_range)
    h, w = value.shape[:2]
    # A new image (Blender numbers the name if it is taken: a bake's own images stay as they are).
    image = bpy.data.images.new(name, w, h, float_buffer=True, alpha=False)
    out = np.ones((h, w, 4), np.float32)
    out[..., :3] = value
    image.pixels.foreach_set(out.ravel())
    image.pack()
    return image


def import_glb(context, filepath):
    """Import `filepath` with Blender's glTF importer and wire each lightmap it carries into the
    imported materials. Returns a summary: objects (name -> its lightmap image), notes, seconds.
    Raises ExportError when the file has no lightmap or the importer fails."""
    t0 = time.perf_counter()
    doc, binary = read_glb(filepath)
    if not any(EXTRAS_KEY in (m.get("extras") or {}) for m in doc.get("materials", [])):
        raise ExportError("%s carries no PhotonLM lightmap (extras.%s)" % (filepath, EXTRAS_KEY))
    if "bool" not in vars(np):  # Blender 3.4's importer uses np.bool, which NumPy 1.24 removed
        np.bool = np.bool_
    before = set(bpy.data.objects)
    result = bpy.ops.import_scene.gltf(filepath=filepath)
    if result != {'FINISHED'}:
        raise ExportError("Blender's glTF importer did not finish (%s)" % ", ".join(result))
    engine = context.scene.render.engine
    images, objects, notes = {}, {}, []
    for obj in (o for o in bpy.data.objects if o not in before and o.type == 'MESH'):
        for slot in obj.material_slots:
            mat = slot.material
            info = mat.get(EXTRAS_KEY) if mat is not None else None
            if info is None:
                continue
            texture, value_range = int(info["texture"]), float(info["range"])
            name = str(info.get("image", "lightmap %d" % texture))
            if texture not in images:
                images[texture] = decoded_image(name, png_bytes(doc, binary, texture), value_range)
            uv_index = int(info.get("texCoord", 1))
            layers = obj.data.uv_layers
            if uv_index >= len(layers):
                notes.append("'%s' has no UV map %d for its lightmap: not wired" % (obj.name, uv_index))
                continue
            for note in wiring.wire_material(mat, images[texture], engine, uv_map=layers[uv_index].name):
                notes.append(note)
            wiring.set_preview(mat, context.scene.photonlm.preview_mode)
            objects[obj.name] = images[texture].name
    if not objects:
        raise ExportError("no imported object's material kept its PhotonLM lightmap")
    if context.scene.photonlm.preview_mode == 'OFF':
        context.scene.photonlm.preview_mode = 'LIGHTMAP'  # shows every wired material's lightmap
    return dict(path=filepath, objects=objects, notes=notes, seconds=time.perf_counter() - t0)
