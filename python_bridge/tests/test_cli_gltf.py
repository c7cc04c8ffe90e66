"""`photonlm gltf SCENE BAKE_DIR -o FILE.glb`: a bake folder as a binary glTF in the form the add-on's export
writes (docs/gltf.md): meshes in glTF's axes, the lightmap UVs as TEXCOORD_1, each lightmap an RGBM PNG that
decodes to its EXR within the encoding's bound, declared by MOZ_lightmap, FB_materials_lightmap and the extras,
light-group layers in the extras; a folder that is not a bake is refused."""
import io
import json
import os
import struct
import subprocess

import numpy as np
import pytest

import photonlm
from test_cli import CLI, QUAD

PIL = pytest.importorskip("PIL.Image")
pytestmark = pytest.mark.skipif(CLI is None or not os.access(CLI, os.X_OK), reason="the photonlm CLI was not found")


def read_glb(path):
    data = open(path, "rb").read()
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    assert magic == b"glTF" and version == 2 and length == len(data)
    n, kind = struct.unpack_from("<I4s", data, 12)
    doc = json.loads(data[20:20 + n])
    m, kind = struct.unpack_from("<I4s", data, 20 + n)
    assert kind == b"BIN\0"
    return doc, data[28 + n:28 + n + m]


def view(doc, binary, index):
    v = doc["bufferViews"][index]
    return binary[v.get("byteOffset", 0):v.get("byteOffset", 0) + v["byteLength"]]


def accessor(doc, binary, index):
    a = doc["accessors"][index]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[a["type"]]
    dtype = {5126: np.float32, 5125: np.uint32}[a["componentType"]]
    return np.frombuffer(view(doc, binary, a["bufferView"]), dtype).reshape(a["count"], width)


def rgbm_decode(doc, binary, texture, value_range):
    """The texture's PNG decoded to (h, w, 3) values, row 0 = bottom (the EXR's order), and the bound."""
    image = doc["images"][doc["textures"][texture]["source"]]
    assert image["mimeType"] == "image/png"
    px = np.asarray(PIL.open(io.BytesIO(view(doc, binary, image["bufferView"]))).convert("RGBA"), np.float64)[::-1]
    px /= 255.0
    return px[..., :3] * px[..., 3:4] * value_range, px[..., 3] * value_range / 510.0


def test_a_bake_folder_becomes_a_glb(tmp_path):
    scene = {
        "version": 1,
        "light_groups": ["sun", "lamp"],
        "materials": [{"name": "grey", "albedo": [0.6, 0.5, 0.4]}],
        "meshes": [dict(QUAD, name="floor", material="grey", lightmap_resolution=8),
                   {"name": "wall", "positions": [-1, 1, 0, 1, 1, 0, 1, 1, 1, -1, 1, 1], "indices": [0, 1, 2, 0, 2, 3],
                    "lightmap_uv": [0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1], "material": "grey",
                    "lightmap_resolution": 4}],
        "lights": [{"type": "SUN", "power": 3, "group": "sun"},
                   {"type": "POINT", "power": 100, "location": [0.3, 0, 0.6], "group": "lamp"}],
        "settings": {"photon_count": 40000, "direct_samples": 4, "seed": 3},
    }
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    bake = tmp_path / "bake"
    r = subprocess.run([CLI, "bake", str(path), "-o", str(bake)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    glb = tmp_path / "scene.glb"
    r = subprocess.run([CLI, "gltf", str(path), str(bake), "-o", str(glb)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    doc, binary = read_glb(glb)
    assert {"MOZ_lightmap", "FB_materials_lightmap"} <= set(doc["extensionsUsed"]) and not doc.get("extensionsRequired")
    nodes = {n["name"]: n for n in doc["nodes"]}
    assert sorted(nodes) == ["floor", "wall"]
    for name, res in (("floor", 8), ("wall", 4)):
        prim, = doc["meshes"][nodes[name]["mesh"]]["primitives"]
        mat = doc["materials"][prim["material"]]
        assert mat["pbrMetallicRoughness"]["baseColorFactor"] == pytest.approx([0.6, 0.5, 0.4, 1.0])
        lm = mat["extras"]["photonlm_lightmap"]
        assert lm["encoding"] == "RGBM" and lm["texCoord"] == 1 and lm["intensity"] == pytest.approx(np.pi * lm["range"])
        assert mat["extensions"]["MOZ_lightmap"] == {"index": lm["texture"], "texCoord": 1, "intensity": lm["intensity"]}
        assert mat["extensions"]["FB_materials_lightmap"]["lightmapTexture"] == {"index": lm["texture"], "texCoord": 1}
        exr = photonlm.read_lightmap_exr(bake / ("%s_lightmap.exr" % name)).rgb
        decoded, bound = rgbm_decode(doc, binary, lm["texture"], lm["range"])
        assert decoded.shape == (res, res, 3)
        assert np.all(np.abs(decoded - exr) <= bound[..., None] * (1 + 1e-6) + 1e-7 * lm["range"])
        # Positions in glTF's axes (y up: Blender's (x, y, z) is (x, z, -y)); TEXCOORD_1 the lightmap UVs, v flipped.
        idx = accessor(doc, binary, prim["indices"]).ravel()
        pos = accessor(doc, binary, prim["attributes"]["POSITION"])[idx]
        uv1 = accessor(doc, binary, prim["attributes"]["TEXCOORD_1"])[idx]
        src = scene["meshes"][0 if name == "floor" else 1]
        p = np.array(src["positions"], np.float32).reshape(-1, 3)[np.array(src["indices"])]
        assert np.allclose(pos, np.stack([p[:, 0], p[:, 2], -p[:, 1]], axis=1))
        uv = np.array(src["lightmap_uv"], np.float32).reshape(-1, 2)
        assert np.allclose(uv1, np.stack([uv[:, 0], 1.0 - uv[:, 1]], axis=1))
        # The light groups' layers, each its own texture, adding up to the lightmap.
        assert [lay["group"] for lay in lm["layers"]] == ["sun", "lamp"]
        total = 0.0
        for lay in lm["layers"]:
            layer, bound = rgbm_decode(doc, binary, lay["texture"], lay["range"])
            exr_layer = photonlm.read_lightmap_exr(bake / ("%s_lightmap.%s.exr" % (name, lay["group"]))).rgb
            assert np.all(np.abs(layer - exr_layer) <= bound[..., None] * (1 + 1e-6) + 1e-7 * lay["range"])
            total = total + exr_layer
        assert np.allclose(total, exr, rtol=1e-4, atol=1e-6)

    r = subprocess.run([CLI, "gltf", str(path), str(tmp_path), "-o", str(tmp_path / "x.glb")], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 1 and "report.json" in r.stderr and not (tmp_path / "x.glb").exists()
