"""Materials: what the engine needs from a Blender material.

Reading (for the bake). The material's active Material Output (Cycles' choice: an output
whose target is CYCLES wins over ALL, the active one wins among equals) is followed
through its Surface link; flatten.py turns the closures it reaches (Principled, Diffuse,
Glossy, Glass, Refraction, Transparent BSDFs and Emission, through Mix and Add Shaders and
node groups) into one diffuse albedo, an emission and a list of specular lobes, with Cycles
3.4's weights. An Image Texture node linked into the colour of the diffuse part (its Vector
unlinked or from a UV Map node) becomes an engine albedo texture (albedo = image x the
diffuse weight) on the UV map it reads (export_textures, texture_uv); one into an emission
colour becomes an emission texture (radiance = image x strength x weight). A procedurally
linked diffuse colour is baked as grey 0.8, other linked emission as none (reported). A
material without nodes uses its viewport colour (material.diffuse_color). What the engine
has no exact counterpart for is reported once per material (flatten.py lists it).

The lightmap preview wiring that a bake adds to the node trees is writeback/wiring.py's.
"""
import os
import shutil
import tempfile

import bpy
import numpy as np

from .. import compat
from . import flatten, meshes

TAG = "photonlm"
ORIGINAL_OUTPUT_KEY = "photonlm_original_output"
FALLBACK_ALBEDO = (0.8, 0.8, 0.8)


class MaterialInfo:
    """What the bake uses from one material, and where its colours come from (for the preview)."""

    def __init__(self, name):
        self.name = name
        self.albedo = FALLBACK_ALBEDO
        self.emission = (0.0, 0.0, 0.0)
        self.lobes = []            # flatten.Lobe: the specular part, in the order the engine sums them
        self.burley = None         # Burley diffuse roughness (Blender 3.x's Principled BSDF), None: Lambert
        self.notes = []            # reports about approximations
        self.color_socket = None   # the input giving the diffuse colour by a link (NodeSocket) or None
        self.preview_factor = 1.0  # the diffuse weight multiplying that colour
        self.emission_color_socket = None   # the emission's inputs when it is one unweighted Emission
        self.emission_strength_socket = None
        self.albedo_texture = None     # TextureRef: Image Texture node into the diffuse colour
        self.emission_texture = None   # TextureRef: Image Texture node into the emission colour
        self.surface = None        # the original Material Output's Surface input (for the preview)

    def purely_diffuse(self):
        return not self.lobes


class TextureRef:
    """An Image Texture node the engine looks up itself: its image and the UV map it reads
    (None = the mesh's active render UV map)."""

    def __init__(self, node, uv_map):
        self.node = node
        self.image = node.image
        self.uv_map = uv_map


def _image_texture(mat, socket, what, info, path=()):
    """TextureRef when socket (inside the node groups `path`) is fed by an Image Texture node the
    engine can look up (an image, its Vector unlinked or from a UV Map node, Repeat extension);
    else None with a note."""
    src = flatten.source(socket, path)
    node = src[0].node if src is not None else None
    if node is None or node.bl_idname != 'ShaderNodeTexImage':
        kind = node.bl_label if node is not None else "a link"
        info.notes.append("material '%s': %s comes from %s (not an Image Texture): baked as grey 0.8"
                          % (mat.name, what, kind) if what == "Base Color" else
                          "material '%s': %s comes from %s (not an Image Texture): baked without emission"
                          % (mat.name, what, kind))
        return None
    if node.image is None:
        info.notes.append("material '%s': Image Texture '%s' has no image: %s ignored" % (mat.name, node.name, what))
        return None
    uv_map = None
    vec = node.inputs['Vector']
    if vec.is_linked:
        vsrc = flatten.source(vec, src[1])
        src = vsrc[0].node if vsrc is not None else None
        if src is None or src.bl_idname != 'ShaderNodeUVMap':
            info.notes.append("material '%s': Image Texture '%s' reads coordinates from '%s' (only a UV Map node "
                              "is supported): the mesh's render UV map is used"
                              % (mat.name, node.name, src.bl_label if src else "?"))
        else:
            uv_map = src.uv_map or None
    if node.extension != 'REPEAT':
        info.notes.append("material '%s': Image Texture '%s' uses extension %s: baked as Repeat"
                          % (mat.name, node.name, node.extension))
    return TextureRef(node, uv_map)


def is_ours(node):
    return node.get(TAG) is not None


def output_nodes(tree, include_ours=False):
    return [n for n in tree.nodes if n.bl_idname == 'ShaderNodeOutputMaterial'
            and (include_ours or not is_ours(n))]


def original_output(tree, target='CYCLES'):
    """The Material Output the material uses without the preview, chosen as Blender chooses
    (exact target before ALL, the active one among equals). While the preview is on, the
    output remembered in ORIGINAL_OUTPUT_KEY counts as the active one."""
    outputs = output_nodes(tree)
    if not outputs:
        return None
    ours_active = any(n.is_active_output for n in output_nodes(tree, True) if is_ours(n))
    remembered = tree.get(ORIGINAL_OUTPUT_KEY)

    def active(n):
        return (n.name == remembered) if (ours_active and remembered) else n.is_active_output

    best = None
    for n in outputs:
        if n.target == 'ALL':
            if best is None or (best.target == 'ALL' and active(n) and not active(best)):
                best = n
        elif n.target == target:
            if best is None or best.target == 'ALL' or (active(n) and not active(best)):
                best = n
    return best


def _follow(socket):
    """The node feeding an input socket, skipping reroutes and muted links; None if unlinked."""
    seen = 0
    while socket is not None and socket.is_linked and seen < 64:
        link = socket.links[0]
        if link.is_muted or not link.is_valid:
            return None
        node = link.from_node
        if node.bl_idname == 'NodeReroute':
            socket = node.inputs[0]
            seen += 1
            continue
        return node
    return None


def read_material(mat, image_means=None):
    """MaterialInfo for a Blender material (None -> the default grey material). image_means
    caches image means between materials of one export."""
    info = MaterialInfo(mat.name if mat else "PhotonLM default")
    if mat is None:
        return info
    if not compat.uses_nodes(mat):
        info.albedo = tuple(float(c) for c in mat.diffuse_color[:3])
        info.notes.append("material '%s' does not use nodes: baked with its viewport colour" % mat.name)
        return _clamp(info)
    out = original_output(mat.node_tree)
    if out is None or flatten.source(out.inputs['Surface']) is None:
        info.notes.append("material '%s' has no shader on its Material Output: baked as grey 0.8" % mat.name)
        return info
    info.surface = out.inputs['Surface']
    image_means = image_means if image_means is not None else {}
    flat = flatten.flatten(info.surface, image_means)
    info.lobes = flat.lobes
    info.burley = flat.burley
    albedo = tuple(flat.albedo)
    if flat.texture_socket is not None:
        socket, path = flat.texture_socket
        ref = _image_texture(mat, socket, "Base Color", info, path)
        if ref is None:
            albedo = tuple(a + flat.texture_factor * c for a, c in zip(albedo, FALLBACK_ALBEDO))
        else:
            info.albedo_texture = ref
            f = flat.texture_factor
            factor = (f, f, f)
            if max(albedo) > 0.0:  # a constant diffuse colour beside the image: folded in by the image's mean
                mean = image_means.get(ref.image.name_full) or flatten.image_mean(ref.image)
                if mean is not None and min(mean[0]) > 0.0:
                    factor = tuple(f + a / m for a, m in zip(albedo, mean[0]))
                flat.approx("a constant diffuse colour beside the image '%s' folded into it by the image's "
                            "mean" % ref.image.name)
            albedo = factor
            if not path:
                info.color_socket, info.preview_factor = socket, f
    elif flat.preview_socket is not None and not flat.preview_socket[1]:
        info.color_socket, info.preview_factor = flat.preview_socket[0], flat.linked_factor
    info.albedo = albedo
    emission = tuple(flat.emission)
    if flat.emission_texture_socket is not None:
        socket, path = flat.emission_texture_socket
        ref = _image_texture(mat, socket, "Emission", info, path)
        if ref is not None:
            info.emission_texture = ref
            if max(emission) > 0.0:
                flat.approx("a constant emission beside the emission image '%s' left out" % ref.image.name)
            emission = (flat.emission_texture_strength,) * 3
    info.emission = emission
    if flat.emission_leaves == 1 and flat.emission_sockets is not None:
        info.emission_color_socket, info.emission_strength_socket = flat.emission_sockets
    for _kind, text in flat.notes:
        info.notes.append("material '%s': %s" % (mat.name, text))
    if flat.approximations:
        info.notes.append("material '%s': approximated for the bake: %s" % (mat.name, "; ".join(flat.approximations)))
    return _clamp(info)


def _clamp(info):
    if any(c > 1.0 for c in info.albedo) or any(c < 0.0 for c in info.albedo):
        info.notes.append("material '%s': albedo %s clamped to [0, 1]"
                          % (info.name, tuple(round(c, 3) for c in info.albedo)))
        info.albedo = tuple(min(max(c, 0.0), 1.0) for c in info.albedo)
    return info


# ---- image textures for the engine ---------------------------------------------------------

# File types the engine decodes itself (native/src/util/image_file.h); Blender decodes the others
# (TIFF, WebP, ...) and the add-on hands over their pixels.
ENGINE_IMAGE_TYPES = (".exr", ".hdr", ".pfm", ".png", ".jpg", ".jpeg", ".bmp", ".tga", ".psd", ".gif")


def engine_reads(path):
    return path.lower().endswith(ENGINE_IMAGE_TYPES)


class TextureFiles:
    """Images handed to the engine: file-backed images by their path where the engine reads the
    file type; packed, generated or edited ones and other file types written to a private
    temporary directory (removed by cleanup())."""

    def __init__(self):
        self.dir = None
        self.paths = {}  # image name -> (path, colorspace)

    def path_of(self, image):
        key = image.name_full
        if key in self.paths:
            return self.paths[key]
        path = bpy.path.abspath(image.filepath, library=image.library) if image.filepath else ""
        space = "srgb" if image.colorspace_settings.name == 'sRGB' else "linear"
        if not (image.source == 'FILE' and not image.packed_file and not image.is_dirty
                and path and os.path.isfile(path) and engine_reads(path)):
            path, space = self._write_pixels(image)
        self.paths[key] = (path, space)
        return self.paths[key]

    def _write_pixels(self, image):
        """The image's pixels as PPM (byte images, as stored: sRGB stays encoded) or PFM (float
        images, scene linear)."""
        if self.dir is None:
            self.dir = tempfile.mkdtemp(prefix="photonlm-images-")
        w, h = image.size
        if w == 0 or h == 0:
            raise ValueError("image '%s' has no pixels" % image.name)
        px = np.empty(w * h * image.channels, np.float32)
        image.pixels.foreach_get(px)
        px = px.reshape(h, w, image.channels)
        rgb = px[..., :3] if image.channels >= 3 else np.repeat(px[..., :1], 3, axis=2)
        name = "%d" % len(self.paths)
        if image.is_float:
            path = os.path.join(self.dir, name + ".pfm")
            with open(path, "wb") as f:  # PFM rows run bottom to top, like Blender's pixels
                f.write(b"PF\n%d %d\n-1.0\n" % (w, h))
                f.write(np.ascontiguousarray(rgb, "<f4").tobytes())
            return path, "linear"
        path = os.path.join(self.dir, name + ".ppm")
        with open(path, "wb") as f:  # PPM rows run top to bottom
            f.write(b"P6\n%d %d\n255\n" % (w, h))
            f.write(np.clip(np.rint(rgb[::-1] * 255.0), 0, 255).astype(np.uint8).tobytes())
        return path, "srgb" if image.colorspace_settings.name == 'sRGB' else "linear"

    def cleanup(self):
        if self.dir is not None:
            shutil.rmtree(self.dir, ignore_errors=True)
            self.dir = None
        self.paths = {}


def export_textures(plm, material_id, info, files, reports):
    """Give engine material material_id the textures of info (if the scene supports them).
    A texture the engine cannot read is reported and the material keeps its fallback colour."""
    if not hasattr(plm, "set_material_texture"):
        if info.albedo_texture or info.emission_texture:
            reports.warning("material '%s': textures are not exported here: their mean is not known, "
                            "baked with constant colours" % info.name)
        return
    for slot, ref in (("albedo", info.albedo_texture), ("emission", info.emission_texture)):
        if ref is None:
            continue
        try:
            path, space = files.path_of(ref.image)
            plm.set_material_texture(material_id, slot, path, space)
        except Exception as e:  # noqa: BLE001 -- reported; the bake goes on without the texture
            reports.warning("material '%s': %s texture '%s' not used: %s"
                            % (info.name, slot, ref.image.name, getattr(e, "message", e)))


def export_lobes(plm, material_id, info, reports):
    """Give engine material material_id the specular lobes of info. A FRESNEL or SPECULAR lobe goes
    as its F0 (color / weight) and weight; the others with weight 1 (their colour carries the mix factors).
    A lobe the engine refuses is reported and left out. A Burley diffuse part (info.burley) goes as
    the material's diffuse model."""
    if info.burley is not None and hasattr(plm, "set_material_diffuse"):
        try:
            plm.set_material_diffuse(material_id, "burley", info.burley)
        except Exception as e:  # noqa: BLE001 -- reported; the bake goes on with Lambert's diffuse
            reports.warning("material '%s': Burley diffuse baked as Lambert: %s" % (info.name, getattr(e, "message", e)))
    if not info.lobes:
        return
    if not hasattr(plm, "add_material_lobe"):
        reports.warning("material '%s': the engine takes no specular lobes here: its %s part is left out"
                        % (info.name, ", ".join(sorted({l.kind for l in info.lobes}))))
        return
    for lobe in info.lobes:
        color, weight = lobe.color, 1.0
        if lobe.kind in flatten.LAYER_KINDS:
            weight = min(max(lobe.weight, 0.0), 1.0)
            color = tuple(min(max(c / lobe.weight, 0.0), 1.0) for c in lobe.color) if lobe.weight > 0.0 \
                else (0.0, 0.0, 0.0)
        try:
            plm.add_material_lobe(material_id, lobe.kind, color, roughness=lobe.roughness, ior=lobe.ior,
                                  abbe=lobe.abbe, weight=weight)
        except Exception as e:  # noqa: BLE001 -- reported; the bake goes on without the lobe
            reports.warning("material '%s': %s lobe left out: %s" % (info.name, lobe.kind, getattr(e, "message", e)))


def texture_uv(mesh, infos, object_name, reports):
    """(T, 3, 2) float32 texture UVs of an evaluated mesh (loop triangles) for its textured
    materials, or None when none is textured. One UV map per mesh: the first textured
    material's (a UV Map node's, else the active render UV map); others are reported."""
    wanted = []
    for info in infos:
        for ref in (info.albedo_texture, info.emission_texture) if info is not None else ():
            if ref is not None and ref.uv_map not in wanted:
                wanted.append(ref.uv_map)
    if not wanted:
        return None
    name = wanted[0]
    layer = meshes.uv_layer(mesh, name)
    if len(wanted) > 1:
        reports.warning("object '%s': its textures read different UV maps %s: all use '%s'"
                        % (object_name, wanted, layer.name if layer else name))
    if layer is None:
        reports.warning("object '%s': no UV map '%s' for its textures: their mean colour is used"
                        % (object_name, name or "(render)"))
        return None
    return meshes.corner_uv(mesh, layer)
