"""File > Export > glTF with PhotonLM lightmaps (.glb): Blender's glTF exporter writes the scene and
each baked object's material carries its lightmap.

Scene: the Cornell box at 16 x 16 texels per object (its maps: UVMap, then lightmap), with the tall
box's maps in the other order (lightmap first: the exporter's TEXCOORD_0, swapped to 1; its base
colour, an image on UVMap, follows UVMap to TEXCOORD_0) and a cube
whose only UV map is its lightmap (TEXCOORD_0 and TEXCOORD_1 share it); baked with the add-on.

Expected, reading the .glb in plain Python (GLB header, JSON and BIN chunks):
- every baked object's node has a mesh whose primitives' materials carry MOZ_lightmap
  {index, texCoord 1, intensity = pi x range} and FB_materials_lightmap {lightmapTexture {index,
  texCoord 1}, lightmapFactor}, and extras.photonlm_lightmap (RGBM, range, linear); both names are in
  extensionsUsed;
- TEXCOORD_1 holds the object's lightmap UVs: every exported triangle (positions and TEXCOORD_1,
  back in Blender's axes and v) matches a triangle of the evaluated mesh to 1e-5 and every triangle
  is matched once; TEXCOORD_0 holds UVMap where the object has it;
- the lightmap PNG, loaded by Blender, holds the RGBM encoding of the baked EXR byte for byte, and
  decoded it equals the EXR texel by texel within the encoding's bound (m x range / 510 per channel;
  at most 1/255 of the texel's largest channel for texels above range / 255);
- round trip: Blender's glTF importer, into an empty scene, gives each object a second UV map equal
  to its lightmap UVs, and its material the extras (the lightmap's texture index, which names a PNG
  in the file). Wiring the lightmap into the imported material is not done by the importer.
- the operator refuses with a message when no object has a lightmap;
- with light groups (the lamp in Light Group "lamp", its only light), extras.photonlm_lightmap lists
  the layers: each object's single layer "lamp" with its own RGBM texture, strength 1 and a white
  tint, whose PNG decodes to the layer's EXR within the encoding's bound;
- with Directional, extras.photonlm_lightmap.sh holds the three L1 bands in glTF's axes (L1_-1 = the
  baked band along Blender's z, L1_0 = minus the band along y, L1_1 = the band along x), each an
  RGBM_SIGNED texture that decodes to the band within m x range / 255.
"""
import json
import math
import os
import struct
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils import kdtree  # noqa: E402

TOL_UV = 1e-5


def build_scene():
    scenes.clear_scene()
    objs = scenes.cornell_box(resolution=16)
    png = scenes.write_texture_png(os.path.join(scenes.out_dir("gltf_export"), "planks.png"))
    objs["tall_box"].data.materials[0] = scenes.textured_material("mat_tall_box_textured", png)
    mesh = objs["tall_box"].data  # UVMap after lightmap
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers["UVMap"].data.foreach_get("uv", uv)
    mesh.uv_layers.remove(mesh.uv_layers["UVMap"])
    mesh.uv_layers.new(name="UVMap").data.foreach_set("uv", uv)
    bpy.ops.mesh.primitive_cube_add(size=0.3, location=(0.55, 0.2, 0.15))
    cube = bpy.context.active_object
    cube.name = "cube"
    cube.data.uv_layers[0].name = "lightmap"  # Blender's fixed cube layout, the only map
    cube.data.materials.append(scenes.diffuse_material("mat_cube", (0.2, 0.4, 0.7)))
    cube.photonlm.resolution = 16
    objs["cube"] = cube
    return {n: o for n, o in objs.items() if n != "light"}


def match_triangles(pos_a, uv_a, pos_b, uv_b):
    """Largest UV difference over triangles of a matched to b by centroid, corners by position;
    inf where a triangle has no counterpart or two share one."""
    if len(pos_a) != len(pos_b):
        return math.inf
    tree = kdtree.KDTree(len(pos_b))
    for i, c in enumerate(pos_b.mean(axis=1)):
        tree.insert(c.tolist(), i)
    tree.balance()
    used, worst = set(), 0.0
    for t, c in enumerate(pos_a.mean(axis=1)):
        _, j, d = tree.find(c.tolist())
        if d > 1e-4 or j in used:
            return math.inf
        used.add(j)
        for k in range(3):
            corner = int(np.argmin(np.linalg.norm(pos_b[j] - pos_a[t, k], axis=1)))
            if np.linalg.norm(pos_b[j, corner] - pos_a[t, k]) > 1e-4:
                return math.inf
            worst = max(worst, float(np.abs(uv_b[j, corner] - uv_a[t, k]).max()))
    return worst


class Glb:
    """A .glb read with struct and json: the JSON and the BIN chunk."""

    def __init__(self, path):
        data = open(path, "rb").read()
        magic, version, length = struct.unpack_from("<4sII", data, 0)
        assert magic == b"glTF" and version == 2 and length == len(data), (magic, version, length)
        n, kind = struct.unpack_from("<I4s", data, 12)
        assert kind == b"JSON"
        self.json = json.loads(data[20:20 + n])
        m, kind = struct.unpack_from("<I4s", data, 20 + n)
        assert kind == b"BIN\0"
        self.bin = data[28 + n:28 + n + m]

    def view(self, index):
        v = self.json["bufferViews"][index]
        return self.bin[v.get("byteOffset", 0):v.get("byteOffset", 0) + v["byteLength"]]

    def accessor(self, index):
        a = self.json["accessors"][index]
        dtype = {5126: np.float32, 5125: np.uint32, 5123: np.uint16, 5121: np.uint8}[a["componentType"]]
        width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[a["type"]]
        v = self.json["bufferViews"][a["bufferView"]]
        assert "byteStride" not in v or v["byteStride"] == width * np.dtype(dtype).itemsize
        raw = np.frombuffer(self.view(a["bufferView"]), dtype, count=a["count"] * width,
                            offset=a.get("byteOffset", 0))
        return raw.reshape(a["count"], width) if width > 1 else raw

    def image_bytes(self, texture_index):
        image = self.json["images"][self.json["textures"][texture_index]["source"]]
        return image.get("mimeType"), self.view(image["bufferView"])

    def triangles(self, prim, attribute):
        """Positions in Blender's axes (T, 3, 3) and `attribute` UVs with Blender's v (T, 3, 2)."""
        idx = self.accessor(prim["indices"]).astype(np.int64)
        p = self.accessor(prim["attributes"]["POSITION"]).astype(np.float64)
        p = np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=1)
        uv = self.accessor(prim["attributes"][attribute]).astype(np.float64).copy()
        uv[:, 1] = 1.0 - uv[:, 1]
        return p[idx].reshape(-1, 3, 3), uv[idx].reshape(-1, 3, 2)


def png_pixels(data, name):
    """An 8-bit PNG's RGBA as Blender loads it, (h, w, 4) uint8 (row 0 = bottom); kept as <name>.png."""
    from photonlm_blender.gltf.rewire import png_rgba
    with open(os.path.join(scenes.out_dir("gltf_export"), name + ".png"), "wb") as f:
        f.write(data)
    return png_rgba(data)


def check_file(checks, glb, objs, lightmap_of, rgbm):
    """lightmap_of(name) -> (UV map, EXR path) of a baked object."""
    used = glb.json.get("extensionsUsed", [])
    checks.check("MOZ_lightmap" in used and "FB_materials_lightmap" in used and not glb.json.get("extensionsRequired"),
                 "extensionsUsed names MOZ_lightmap and FB_materials_lightmap (used: %s), none required" % used)
    nodes = {n["name"]: n for n in glb.json["nodes"]}
    worst_rel = 0.0
    for name, obj in sorted(objs.items()):
        node = nodes.get(name)
        if not checks.check(node is not None and "mesh" in node, "'%s' is a node with a mesh" % name):
            continue
        prims = glb.json["meshes"][node["mesh"]]["primitives"]
        ok_ext, textures = True, set()
        for prim in prims:
            mat = glb.json["materials"][prim["material"]]
            ext = mat.get("extensions", {})
            moz, fb = ext.get("MOZ_lightmap", {}), ext.get("FB_materials_lightmap", {})
            extras = mat.get("extras", {}).get("photonlm_lightmap", {})
            rng = extras.get("range", -1.0)
            ok_ext &= (moz.get("texCoord") == 1 and fb.get("lightmapTexture", {}).get("texCoord") == 1
                       and moz.get("index") == fb["lightmapTexture"]["index"] == extras.get("texture")
                       and abs(moz.get("intensity", 0) - math.pi * rng) < 1e-6 * rng
                       and fb.get("lightmapFactor") == [moz["intensity"]] * 3
                       and extras.get("encoding") == "RGBM" and extras.get("colorSpace") == "linear"
                       and extras.get("object") == name)
            textures.add((moz.get("index"), rng))
        checks.check(ok_ext and len(textures) == 1, "'%s': its material carries MOZ_lightmap, FB_materials_lightmap "
                     "and extras on texture %s, texCoord 1" % (name, sorted(textures)))
        uv_name, exr_path = lightmap_of(name)
        lm_pos, lm_uv = scenes.evaluated_lightmap_triangles(obj, uv_name, world=False)
        got = [glb.triangles(p, "TEXCOORD_1") for p in prims]
        diff = match_triangles(np.concatenate([g[0] for g in got]), np.concatenate([g[1] for g in got]), lm_pos, lm_uv)
        checks.check(diff <= TOL_UV, "'%s': TEXCOORD_1 = its UV map '%s', triangle by triangle (%d triangles, "
                     "max |diff| %.2g)" % (name, uv_name, len(lm_pos), diff))
        if "UVMap" in obj.data.uv_layers:
            tex_pos, tex_uv = scenes.evaluated_lightmap_triangles(obj, "UVMap", world=False)
            got0 = [glb.triangles(p, "TEXCOORD_0") for p in prims]
            d0 = match_triangles(np.concatenate([g[0] for g in got0]), np.concatenate([g[1] for g in got0]),
                                 tex_pos, tex_uv)
            checks.check(d0 <= TOL_UV, "'%s': TEXCOORD_0 = its UVMap (max |diff| %.2g)" % (name, d0))
        (tex, rng), = textures
        mime, data = glb.image_bytes(tex)
        px = png_pixels(data, name)
        exr = scenes.exr_rgb(exr_path)
        enc = rgbm.encode(exr, rng)
        checks.check(mime == "image/png" and px.shape == enc.shape and np.array_equal(px, enc),
                     "'%s': the PNG (%d bytes, %s) holds the RGBM encoding of its EXR byte for byte"
                     % (name, len(data), "x".join(map(str, px.shape))))
        dec = rgbm.decode(px, rng)
        err = np.abs(dec - exr)
        bound = rgbm.error_bound(px, rng)[..., None] * (1 + 1e-6) + 1e-7 * rng
        peak = exr.max(axis=2)
        bright = peak >= rng / 255.0
        rel = float((err.max(axis=2)[bright] / peak[bright]).max()) if bright.any() else 0.0
        worst_rel = max(worst_rel, rel)
        checks.check(bool(np.all(err <= bound)) and rel <= 1.0 / 255.0 + 1e-6 and abs(rng - float(exr.max())) <= 1e-6 * rng,
                     "'%s': decoded = EXR within m x range / 510 per texel (max |diff| %.3g, range %.4g; above "
                     "range/255 max relative error %.4f %%)" % (name, float(err.max()), rng, 100 * rel))
    return worst_rel


def check_import(checks, path, objs, glb):
    if "bool" not in vars(np):  # Blender 3.4's importer uses np.bool, which NumPy 1.24 (Debian 12's) removed
        np.bool = np.bool_
    before = set(bpy.data.objects)
    bpy.ops.scene.new(type='EMPTY')
    res = bpy.ops.import_scene.gltf(filepath=path)
    new = [o for o in bpy.data.objects if o not in before and o.type == 'MESH']
    checks.check(res == {'FINISHED'} and len(new) == len(objs),
                 "the importer brings %d mesh objects back (%s)" % (len(new), res))
    for obj in new:
        base = obj.name.rsplit(".", 1)[0] if obj.name not in objs else obj.name
        orig = objs.get(base)
        if orig is None:
            checks.check(False, "imported '%s' matches no exported object" % obj.name)
            continue
        lm_pos, lm_uv = scenes.evaluated_lightmap_triangles(orig, "lightmap", world=False)
        layers = obj.data.uv_layers
        diff = math.inf
        if len(layers) >= 2:
            pos, uv = scenes.evaluated_lightmap_triangles(obj, layers[1].name, world=False)
            diff = match_triangles(pos, uv, lm_pos, lm_uv)
        checks.check(diff <= TOL_UV, "imported '%s': second UV map '%s' = the lightmap UVs (max |diff| %.2g)"
                     % (base, layers[1].name if len(layers) >= 2 else None, diff))
        mat = obj.active_material
        info = mat.get("photonlm_lightmap") if mat is not None else None
        ok = False
        if info is not None:
            mime, data = glb.image_bytes(int(info["texture"]))
            ok = mime == "image/png" and data[:8] == b"\x89PNG\r\n\x1a\n"
        checks.check(ok, "imported '%s': material '%s' keeps extras.photonlm_lightmap, whose texture is a PNG in the file"
                     % (base, mat.name if mat else None))


def active_outputs(objs):
    return {o.name: [n.name for n in o.active_material.node_tree.nodes
                     if n.bl_idname == 'ShaderNodeOutputMaterial' and n.is_active_output] for o in objs.values()}


def main():
    checks = scenes.Checks("gltf_export")
    scenes.enable_gltf_addons()
    from photonlm_blender.gltf import rgbm
    scenes.clear_scene()
    scenes.cornell_box(resolution=8)
    out = scenes.out_dir("gltf_export")
    path = os.path.join(out, "cornell.glb")
    try:
        res = bpy.ops.photonlm.export_gltf(filepath=path)
    except RuntimeError as e:
        res = str(e)
    checks.check("bake lightmaps first" in str(res), "with nothing baked the export refuses (%s)" % res)

    objs = build_scene()
    bpy.context.scene.photonlm.output_dir = out
    last = scenes.photonlm_bake(300_000, 16, seed=3, target_error=0.0)
    bpy.context.scene.photonlm.preview_mode = 'LIGHTMAP'
    checks.check(sorted(last["objects"]) == sorted(objs), "baked %s" % sorted(last["objects"]))
    outputs_before = active_outputs(objs)
    t0 = time.perf_counter()
    res = bpy.ops.photonlm.export_gltf(filepath=path)
    seconds = time.perf_counter() - t0
    size = os.path.getsize(path) if os.path.exists(path) else 0
    checks.check(res == {'FINISHED'}, "File > Export > glTF with PhotonLM lightmaps: %s, %d bytes in %.2f s"
                 % (res, size, seconds))
    glb = Glb(path)
    images = [im.get("name") for im in glb.json.get("images", [])]
    checks.check(len(images) == len(objs) + 1 and set(o + "_lightmap" for o in objs) <= set(images)
                 and not any("emissiveTexture" in m for m in glb.json["materials"]),
                 "the file's images are the lightmaps and the tall box's base colour (%d; the materials are exported "
                 "with their own shading, not the lightmap preview)" % len(images))
    tall = glb.json["nodes"][[n["name"] for n in glb.json["nodes"]].index("tall_box")]
    tall_mat = glb.json["materials"][glb.json["meshes"][tall["mesh"]]["primitives"][0]["material"]]
    base = tall_mat.get("pbrMetallicRoughness", {}).get("baseColorTexture", {})
    checks.check("index" in base and base.get("texCoord", 0) == 0,
                 "the tall box's base colour texture follows UVMap to TEXCOORD_0 (%s)" % base)
    checks.check(active_outputs(objs) == outputs_before,
                 "after the export every material's active output is the one before (%s)"
                 % sorted({tuple(v) for v in active_outputs(objs).values()}))
    worst = check_file(checks, glb, objs, lambda n: ("lightmap", last["objects"][n]["path"]), rgbm)
    print("largest relative error above range/255: %.4f %% (bound %.4f %%)" % (100 * worst, 100 / 255.0))

    # Atlas pages: objects share a page's texture, read through the UV map 'PhotonLM Atlas'.
    s = bpy.context.scene.photonlm
    s.lightmap_layout, s.atlas_size = 'ATLAS', '512'
    scenes.photonlm_bake(300_000, 16, seed=3, target_error=0.0)
    atlas_path = os.path.join(out, "cornell_atlas.glb")
    res = bpy.ops.photonlm.export_gltf(filepath=atlas_path)
    atlas = Glb(atlas_path)
    pages = {o["photonlm_atlas_page"] for o in objs.values()}
    checks.check(res == {'FINISHED'} and sorted(im["name"] for im in atlas.json["images"]
                                                 if im["name"].endswith("_lightmap")) == sorted(pages),
                 "atlas: the file's images are the %d page(s) %s, %d bytes" % (len(pages), sorted(pages),
                                                                              os.path.getsize(atlas_path)))

    def page_of(name):
        image = bpy.data.images[objs[name]["photonlm_atlas_page"]]
        return "PhotonLM Atlas", bpy.path.abspath(image.filepath)
    worst = check_file(checks, atlas, objs, page_of, rgbm)
    print("atlas: largest relative error above range/255: %.4f %%" % (100 * worst))
    s.lightmap_layout = 'OBJECT'
    check_light_groups(checks, objs, out, rgbm)
    check_sh(checks, objs, out, rgbm)
    check_import(checks, path, objs, glb)
    checks.finish()


def check_light_groups(checks, objs, out, rgbm):
    """The lamp in Light Group "lamp": every lightmap's one layer, in the extras with its own texture."""
    from photonlm_blender.writeback import lightgroups
    bpy.context.view_layer.lightgroups.add(name="lamp")
    bpy.data.objects["ceiling_light"].lightgroup = "lamp"
    last = scenes.photonlm_bake(300_000, 16, seed=3, target_error=0.0)
    checks.check(last["stats"].get("light_layers") == "lamp", "the bake's layers: %s" % last["stats"].get("light_layers"))
    path = os.path.join(out, "cornell_groups.glb")
    res = bpy.ops.photonlm.export_gltf(filepath=path)
    glb = Glb(path)
    nodes = {n["name"]: n for n in glb.json["nodes"]}
    worst = 0.0
    for name in objs:
        prim = glb.json["meshes"][nodes[name]["mesh"]]["primitives"][0]
        extras = glb.json["materials"][prim["material"]].get("extras", {}).get("photonlm_lightmap", {})
        layers = extras.get("layers", [])
        ok = (res == {'FINISHED'} and [lay.get("group") for lay in layers] == ["lamp"]
              and layers[0]["texture"] != extras.get("texture") and layers[0]["strength"] == 1.0
              and layers[0]["tint"] == [1.0, 1.0, 1.0]
              and abs(layers[0]["intensity"] - math.pi * layers[0]["range"]) <= 1e-6 * layers[0]["intensity"])
        checks.check(ok, "'%s': the extras list the layer 'lamp' with its own texture (%s)" % (name, layers))
        if not ok:
            continue
        layer_exr = lightgroups.layer_file(last["objects"][name]["path"], "lamp")
        exr = scenes.exr_rgb(layer_exr)
        px = png_pixels(glb.image_bytes(layers[0]["texture"])[1], name + "_lamp")
        err = np.abs(rgbm.decode(px, layers[0]["range"]) - exr)
        bound = rgbm.error_bound(px, layers[0]["range"])[..., None] * (1 + 1e-6) + 1e-7 * layers[0]["range"]
        worst = max(worst, float((err - bound).max()))
    checks.check(worst <= 0.0, "every layer's PNG decodes to its EXR within the encoding's bound")
    bpy.data.objects["ceiling_light"].lightgroup = ""  # the group, named by no light, gives no layer


def check_sh(checks, objs, out, rgbm):
    """A directional bake: the extras' "sh" bands, in glTF's axes, decode to the baked bands."""
    from photonlm_blender.writeback import directional
    bpy.context.scene.photonlm.directional = True
    last = scenes.photonlm_bake(300_000, 16, seed=3, target_error=0.0)
    path = os.path.join(out, "cornell_sh.glb")
    res = bpy.ops.photonlm.export_gltf(filepath=path)
    glb = Glb(path)
    nodes = {n["name"]: n for n in glb.json["nodes"]}
    worst, ok_all = 0.0, res == {'FINISHED'}
    for name in objs:
        prim = glb.json["meshes"][nodes[name]["mesh"]]["primitives"][0]
        sh = glb.json["materials"][prim["material"]].get("extras", {}).get("photonlm_lightmap", {}).get("sh", {})
        bands = sh.get("bands", [])
        ok = sh.get("encoding") == "RGBM_SIGNED" and [b.get("m") for b in bands] == [-1, 0, 1]
        ok_all = ok_all and ok
        if not ok:
            continue
        baked = [scenes.exr_rgb(directional.band_file(last["objects"][name]["path"], b)) for b in directional.BANDS]
        want = {-1: baked[1], 0: -baked[0], 1: baked[2]}  # Blender (x, y, z) is glTF (x, -z, y)
        for b in bands:
            px = png_pixels(glb.image_bytes(b["texture"])[1], "%s_sh%d" % (name, b["m"]))
            err = np.abs(rgbm.decode_signed(px, b["range"]) - want[b["m"]])
            bound = px[..., 3:4].astype(np.float64) / 255.0 * b["range"] / 255.0 * (1 + 1e-6) + 1e-7 * b["range"]
            worst = max(worst, float((err - bound).max()))
    checks.check(ok_all, "directional: every material's extras hold the L1 bands m = -1, 0, 1 (RGBM_SIGNED)")
    checks.check(worst <= 0.0, "directional: each band decodes to the baked band in glTF's axes within m range / 255")
    bpy.context.scene.photonlm.directional = False


main()
