"""A .glb of the scene with the baked lightmaps, written by Blender's own glTF exporter.

    summary = export_glb(context, filepath, use_selection=False)

Blender's exporter (io_scene_gltf2) writes the file; while export_glb runs it, the hook class
GltfHook (the add-on's package exposes it as glTF2ExportUserExtension, where the exporter looks
for it) gives each baked object's node:
- TEXCOORD_1 = the object's lightmap UV map (its atlas UV map in an atlas), as the exporter wrote it
  from the evaluated mesh (modifiers applied): the exporter numbers UV maps in the mesh's order, so
  the lightmap map is swapped with the map at 1 (and the material's textures follow it), or shared
  as 0 and 1 where it is the mesh's only map;
- a copy of each of its materials with the lightmap: its texture (one per image: an atlas page is
  shared) holds the lightmap in RGBM (rgbm.py) as a PNG, clamped, linear filtering, and the
  material carries it as
      extensions.MOZ_lightmap          {index, texCoord: 1, intensity}
      extensions.FB_materials_lightmap {lightmapTexture: {index, texCoord: 1}, lightmapFactor: [i, i, i]}
      extras.photonlm_lightmap         {encoding: "RGBM", range, colorSpace: "linear", texture, texCoord,
                                        intensity, object, image[, layers]}
  with intensity = pi x range: decoded rgb x a (in [0, 1]) times intensity is the irradiance the
  lightmap holds (its texels are irradiance / pi in Cycles' units), what three.js's lightMap with
  lightMapIntensity takes. A bake with light groups adds `layers`: per group (in the scene's
  order) {group, texture, range, intensity, strength, tint}, each layer's own RGBM texture; the
  layers add up to the lightmap, and strength x tint are the panel's mix when the file was written.
  A directional bake adds `sh`: the L1 bands in glTF's axes (y up) as Godot 4 lays them out, each in
  its own texture encoded RGBM_SIGNED (value = (2 rgb - 1) x a x range), L0 being the lightmap's
  value / (2 x 0.282095); a surface of unit normal n (glTF's axes) receives
  0.282095 L0 + 0.32573 (L1_-1 n.y + L1_0 n.z + L1_1 n.x) (docs/gltf.md).
The materials are exported with their preview off (their own shading, not the lightmap preview)
and put back as they were. The hook does nothing in other glTF exports.
"""
import copy
import math
import os
import time

import bpy
import numpy as np

from .. import compat
from ..writeback import directional, lightgroups, wiring
from ..writeback.atlas import object_lightmap
from . import rgbm

EXTRAS_KEY = "photonlm_lightmap"
MOZ = "MOZ_lightmap"
FB = "FB_materials_lightmap"
TEXCOORD = 1                      # the lightmap's UV set in the file
IRRADIANCE_PER_TEXEL = math.pi    # a texel holds irradiance / pi
LINEAR, CLAMP_TO_EDGE = 9729, 33071


class ExportError(Exception):
    """An export that cannot be done; the message is for the user."""


class _Export:
    """One export under way: the baked objects' lightmaps and what the hook made of them."""

    def __init__(self, lightmaps):
        self.lightmaps = lightmaps    # object name -> (bpy image, UV map name, its index in the evaluated mesh)
        self.textures = {}            # image name -> (glTF texture, range, PNG bytes)
        self.sh_bands = {}            # lightmap image name -> its extras' "sh" (directional bakes)
        self.materials = {}           # (id of the exporter's material, object name) -> our copy
        self.objects = {}             # object name -> names of its materials given the lightmap
        self.notes = []
        self.errors = []

    def texture(self, image, types):
        if image.name in self.textures:
            return self.textures[image.name]
        _, BinaryData, io = types
        w, h = image.size
        if w * h == 0:
            raise ExportError("lightmap image '%s' has no pixels (its file is missing?)" % image.name)
        px = np.empty(w * h * 4, np.float32)
        image.pixels.foreach_get(px)
        rgb = px.reshape(h, w, 4)[..., :3]
        value_range = rgbm.lightmap_range(rgb)
        data = rgbm.png(rgbm.encode(rgb, value_range))
        source = io.Image(buffer_view=BinaryData(data=data), extensions=None, extras=None,
                          mime_type="image/png", name=image.name, uri=None)
        sampler = io.Sampler(extensions=None, extras=None, mag_filter=LINEAR, min_filter=LINEAR, name=None,
                             wrap_s=CLAMP_TO_EDGE, wrap_t=CLAMP_TO_EDGE)
        texture = io.Texture(extensions=None, extras=None, name=image.name, sampler=sampler, source=source)
        self.textures[image.name] = (texture, value_range, data)
        return self.textures[image.name]

    def layers(self, image, types):
        """The light-group layers of lightmap image `image` (lightgroups.layer_image_name), as the
        extras list them; empty without groups."""
        out = []
        for item in bpy.context.scene.photonlm.light_groups:
            layer_image = bpy.data.images.get(lightgroups.layer_image_name(image.name, item.name))
            if layer_image is None:
                continue
            texture, value_range, _ = self.texture(layer_image, types)
            out.append({"group": item.name, "texture": texture, "range": value_range,
                        "intensity": IRRADIANCE_PER_TEXEL * value_range, "strength": item.strength,
                        "tint": list(item.tint)[:3]})
        return out

    def signed_texture(self, name, values, types):
        """A texture of signed values (h, w, 3), RGBM_SIGNED; (texture, range)."""
        _, BinaryData, io = types
        value_range = rgbm.signed_range(values)
        data = rgbm.png(rgbm.encode_signed(values, value_range))
        source = io.Image(buffer_view=BinaryData(data=data), extensions=None, extras=None,
                          mime_type="image/png", name=name, uri=None)
        sampler = io.Sampler(extensions=None, extras=None, mag_filter=LINEAR, min_filter=LINEAR, name=None,
                             wrap_s=CLAMP_TO_EDGE, wrap_t=CLAMP_TO_EDGE)
        texture = io.Texture(extensions=None, extras=None, name=name, sampler=sampler, source=source)
        self.textures[name] = (texture, value_range, data)
        return texture, value_range

    def sh(self, image, types):
        """The L1 bands of lightmap image `image` (writeback/directional.py) in glTF's axes, as the
        extras list them; None without them. Blender's (x, y, z) is glTF's (x, -z, y): glTF's L1_-1
        (its y) is Blender's band 2 (z), L1_0 (its z) minus band 1 (y), L1_1 (x) band 3."""
        bands = [bpy.data.images.get(directional.band_image_name(image.name, b)) for b in directional.BANDS]
        if any(b is None for b in bands):
            return None
        if image.name in self.sh_bands:
            return self.sh_bands[image.name]
        values = []
        for b in bands:
            w, h = b.size
            px = np.empty(w * h * 4, np.float32)
            b.pixels.foreach_get(px)
            values.append(px.reshape(h, w, 4)[..., :3])
        out = {"layout": "Godot 4 SH L1", "axes": "glTF (y up)", "encoding": rgbm.SIGNED,
               "decode": "value = (2 * rgb - 1) * a * range", "l0": "the lightmap's value / (2 * 0.282095)",
               "evaluate": "0.282095 * L0 + 0.32573 * (L1_-1 * n.y + L1_0 * n.z + L1_1 * n.x)", "bands": []}
        for m, name, v in ((-1, "L1_-1", values[1]), (0, "L1_0", -values[0]), (1, "L1_1", values[2])):
            texture, value_range = self.signed_texture("%s_%s" % (image.name, name), v, types)
            out["bands"].append({"m": m, "texture": texture, "range": value_range})
        self.sh_bands[image.name] = out
        return out

    def node(self, node, obj):
        entry = self.lightmaps.get(obj.name)
        mesh = getattr(node, "mesh", None)
        if entry is None or mesh is None:
            return
        image, uv_name, uv_index = entry
        types = compat.gltf_exporter_types(node)
        Extension, _, io = types
        # The node's own copy of the mesh and its primitives (the accessors are shared): the exporter
        # may give one mesh to several nodes, and the others keep it as it was.
        mesh = copy.copy(mesh)
        mesh.primitives = [copy.copy(p) for p in mesh.primitives]
        node.mesh = mesh
        texture, value_range, _ = self.texture(image, types)
        intensity = IRRADIANCE_PER_TEXEL * value_range
        layers = self.layers(image, types)
        sh = self.sh(image, types)
        names = self.objects.setdefault(obj.name, [])
        for prim in mesh.primitives:
            attrs = dict(prim.attributes)
            key = "TEXCOORD_%d" % uv_index
            if key not in attrs:
                raise ExportError("'%s': the exporter wrote no %s for UV map '%s'" % (obj.name, key, uv_name))
            remap = {}
            if uv_index != TEXCOORD and "TEXCOORD_%d" % TEXCOORD in attrs:
                other = "TEXCOORD_%d" % TEXCOORD
                attrs[other], attrs[key] = attrs[key], attrs[other]
                remap = {TEXCOORD: uv_index, uv_index: TEXCOORD}
            elif uv_index != TEXCOORD:  # the only UV map: TEXCOORD_0 and TEXCOORD_1 share it
                attrs["TEXCOORD_%d" % TEXCOORD] = attrs[key]
            prim.attributes = attrs
            if prim.material is None:
                self.notes.append("'%s' has a face without a material: no lightmap on it in the file" % obj.name)
                continue
            mkey = (id(prim.material), obj.name)
            if mkey not in self.materials:
                mat = _remapped(prim.material, remap)
                mat.extensions = dict(mat.extensions or {})
                mat.extensions[MOZ] = Extension(MOZ, {"index": texture, "texCoord": TEXCOORD,
                                                      "intensity": intensity}, False)
                info = io.TextureInfo(extensions=None, extras=None, index=texture, tex_coord=TEXCOORD)
                mat.extensions[FB] = Extension(FB, {"lightmapTexture": info,
                                                    "lightmapFactor": [intensity] * 3}, False)
                extras = dict(mat.extras) if isinstance(mat.extras, dict) else {}
                extras[EXTRAS_KEY] = {"encoding": rgbm.ENCODING, "range": value_range, "colorSpace": "linear",
                                      "decode": "value = rgb * a * range", "units": "irradiance / pi",
                                      "intensity": intensity, "texture": texture, "texCoord": TEXCOORD,
                                      "object": obj.name, "image": image.name}
                if layers:
                    extras[EXTRAS_KEY]["layers"] = layers
                if sh:
                    extras[EXTRAS_KEY]["sh"] = sh
                mat.extras = extras
                self.materials[mkey] = mat
                names.append(mat.name)
            prim.material = self.materials[mkey]


def _remapped(value, remap, depth=0):
    """A copy of a glTF material (or a part of it) whose texture references use the UV sets as
    `remap` renumbers them (tex_coord and KHR_texture_transform's texCoord). Textures and images
    are shared, not copied (the exporter writes each object once)."""
    if isinstance(value, dict):
        out = {k: _remapped(v, remap, depth + 1) for k, v in value.items()}
        if "texCoord" in out and isinstance(out["texCoord"], int):
            out["texCoord"] = remap.get(out["texCoord"], out["texCoord"])
        return out
    if isinstance(value, list):
        return [_remapped(v, remap, depth + 1) for v in value]
    kind = type(value).__name__
    if depth == 0 or kind in ("MaterialPBRMetallicRoughness", "Extension") or hasattr(value, "tex_coord"):
        out = copy.copy(value)
        for k, v in vars(value).items():
            if k not in ("index", "source", "sampler"):
                setattr(out, k, _remapped(v, remap, depth + 1))
        if hasattr(out, "tex_coord") and hasattr(out, "index"):
            t = out.tex_coord or 0
            out.tex_coord = remap.get(t, t)
        return out
    return value


_CURRENT = []  # the export under way: set only while export_glb runs the exporter (one at a time)


class GltfHook:
    """The glTF exporter's user extension (glTF2ExportUserExtension): the exporter makes one per
    export and calls gather_node_hook for every node. Active only inside export_glb; its errors
    are kept and raised by export_glb (the exporter prints and drops a hook's exceptions)."""

    def gather_node_hook(self, gltf2_node, blender_object, export_settings):
        if not _CURRENT or blender_object is None:
            return
        state = _CURRENT[-1]
        try:
            state.node(gltf2_node, blender_object)
        except Exception as e:  # noqa: BLE001 -- kept for export_glb to raise
            state.errors.append(e)


def baked_lightmaps(context, objects):
    """{object name: (image, UV map name, index of that map in the evaluated mesh)} of the mesh
    objects among `objects` that have a lightmap; notes for those whose map is missing."""
    depsgraph = context.evaluated_depsgraph_get()
    out, notes = {}, []
    for obj in objects:
        if obj.type != 'MESH':
            continue
        image, uv_name = object_lightmap(obj)
        if image is None:
            continue
        layers = [layer.name for layer in obj.evaluated_get(depsgraph).data.uv_layers]
        if uv_name not in layers:
            notes.append("'%s' has no UV map '%s' (bake again): exported without its lightmap" % (obj.name, uv_name))
            continue
        out[obj.name] = (image, uv_name, layers.index(uv_name))
    return out, notes


def export_glb(context, filepath, use_selection=False):
    """Write the visible objects (or the selected ones) to a .glb with Blender's glTF exporter,
    each baked object with its lightmap (see the module text). Returns a summary: objects (name ->
    materials given the lightmap), textures (image name -> range, PNG bytes), notes, seconds.
    Raises ExportError when nothing is baked or the exporter did not take the lightmaps."""
    t0 = time.perf_counter()
    objects = context.selected_objects if use_selection else context.visible_objects
    lightmaps, notes = baked_lightmaps(context, objects)
    if not lightmaps:
        raise ExportError("no object to export has a lightmap: bake lightmaps first")
    state = _Export(lightmaps)
    state.notes += notes
    materials = {slot.material for name in lightmaps for slot in bpy.data.objects[name].material_slots
                 if slot.material is not None and wiring.is_wired(slot.material)}
    mode = context.scene.photonlm.preview_mode
    _CURRENT.append(state)
    try:
        for mat in materials:
            wiring.set_preview(mat, 'OFF')
        result = bpy.ops.export_scene.gltf(
            filepath=filepath, export_format='GLB', use_selection=use_selection, use_visible=True, use_renderable=True,
            export_apply=True, export_texcoords=True, export_normals=True, export_materials='EXPORT',
            export_cameras=False, export_lights=False, export_animations=False)
    finally:
        _CURRENT.remove(state)
        for mat in materials:
            wiring.set_preview(mat, mode)
    if state.errors:
        raise ExportError("the lightmaps could not be added: %s" % state.errors[0]) from state.errors[0]
    if result != {'FINISHED'}:
        raise ExportError("Blender's glTF exporter did not finish (%s)" % ", ".join(result))
    missing = sorted(set(lightmaps) - set(state.objects))
    if len(missing) == len(lightmaps):
        raise ExportError("Blender's glTF exporter did not call PhotonLM's hook: enable the add-on in "
                          "Preferences > Add-ons (an add-on run as a script is not seen by the exporter)")
    for name in missing:
        state.notes.append("'%s' was not exported (hidden, or not selected)" % name)
    return dict(path=filepath, objects=state.objects, notes=state.notes, seconds=time.perf_counter() - t0,
                textures={name: dict(range=r, png_bytes=len(data)) for name, (_, r, data) in state.textures.items()},
                size=os.path.getsize(filepath))
