"""Directional lightmaps (SH L1) through the bridge and the CLI: the bands in Godot 4's layout, L0 the
lightmap's, the light's direction that of the sun; files per band; bad requests refused."""
import json
import os
import subprocess

import numpy as np
import pytest

import photonlm
from scenes import plane, rotation_x
from test_cli import CLI, QUAD

EVAL0, EVAL1 = 0.28209479177387814, 0.32573500793527993  # photonlm.h, "Directional lightmaps"


def sunny_floor(scene, zenith):
    """A floor alone under a sun `zenith` radians from the zenith, towards -y."""
    scene.add_material(albedo=0.5)
    pos, tri, uv = plane(2.0)
    floor = scene.add_mesh("floor", pos, tri, uv, resolution=16)
    scene.add_light("SUN", power=3.0, matrix=rotation_x(zenith))
    return floor


def light_direction(sh):
    """Per texel and channel the direction the texel's light comes from (D + V n / 2, n = +z), unit."""
    value = 2.0 * EVAL0 * sh[0]
    d = np.stack([EVAL1 * sh[3], EVAL1 * sh[1], EVAL1 * sh[2] + 0.5 * value], axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True), value


def test_sh_bands_point_at_the_sun_and_l0_is_the_lightmap():
    zenith = 0.6
    with photonlm.Scene() as scene:
        floor = sunny_floor(scene, zenith)
        with scene.bake(photons=20000, direct_samples=16, directional=True) as r:
            assert r.directional
            sh = r.lightmap_sh(floor)
            lightmap = r.lightmap(floor)
    assert sh.shape == (4, 16, 16, 3)
    direction, value = light_direction(sh)
    assert np.allclose(value, lightmap.rgb, rtol=1e-5)
    sun = np.array([0.0, -np.sin(zenith), np.cos(zenith)])
    angle = np.degrees(np.arccos(np.clip(direction @ sun, -1.0, 1.0)))
    assert angle.max() < 1.0, angle.max()


def test_plain_bakes_have_no_bands_and_bad_values_are_refused():
    with photonlm.Scene() as scene:
        floor = sunny_floor(scene, 0.3)
        with scene.bake(photons=5000, direct_samples=4) as r:
            assert not r.directional
            with pytest.raises(photonlm.PhotonlmError, match="no directional lightmaps"):
                r.lightmap_sh(floor)
        with pytest.raises(ValueError, match="directional must be True or False"):
            scene.bake(photons=5000, directional="yes")
        group = scene.add_light_group("sun")
        scene.set_light_group(group, light=0)
        with pytest.raises(photonlm.PhotonlmError, match="light groups"):
            scene.bake(photons=5000, directional=True)


@pytest.mark.skipif(CLI is None or not os.access(CLI, os.X_OK), reason="the photonlm CLI was not found")
def test_cli_writes_the_bands_and_merges_them_as_one_machine(tmp_path):
    scene = {
        "version": 1,
        "materials": [{"name": "grey", "albedo": 0.6}],
        "meshes": [dict(QUAD, name="floor", material="grey", lightmap_resolution=8)],
        "lights": [{"type": "SUN", "power": 3},
                   {"type": "POINT", "power": 100, "location": [0.5, 0, 1]}],
        "world": {"radiance": [0.2, 0.3, 0.5]},
        "settings": {"photon_count": 40000, "direct_samples": 4, "seed": 1, "directional": True},
    }
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))

    def cli(*args):
        r = subprocess.run([CLI] + [str(a) for a in args], capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        return r
    cli("bake", path, "-o", tmp_path / "one")
    bands = ["floor_lightmap_sh%d.exr" % b for b in range(4)]
    assert sorted(os.listdir(tmp_path / "one")) == sorted(["floor_lightmap.exr", "report.json"] + bands)
    report = json.loads((tmp_path / "one" / "report.json").read_text())
    assert report["settings"]["directional"] is True
    assert report["meshes"][0]["sh"] == bands
    l0 = photonlm.read_lightmap_exr(tmp_path / "one" / bands[0]).rgb
    whole = photonlm.read_lightmap_exr(tmp_path / "one" / "floor_lightmap.exr").rgb
    assert np.allclose(2.0 * EVAL0 * l0, whole, rtol=1e-5)
    for k in (1, 2):
        cli("bake", path, "--shard", "%d/2" % k, "-o", tmp_path / "parts")
    cli("merge", tmp_path / "parts", "--scene", path, "-o", tmp_path / "merged")
    for name in ["floor_lightmap.exr"] + bands:
        assert (tmp_path / "one" / name).read_bytes() == (tmp_path / "merged" / name).read_bytes(), name
    # photonlm gltf: the bands in the extras, in glTF's axes (Blender's (x, y, z) is glTF's (x, -z, y)).
    from test_cli_gltf import read_glb, view
    from PIL import Image
    import io
    cli("gltf", path, tmp_path / "one", "-o", tmp_path / "scene.glb")
    doc, binary = read_glb(tmp_path / "scene.glb")
    sh = doc["materials"][0]["extras"]["photonlm_lightmap"]["sh"]
    assert sh["encoding"] == "RGBM_SIGNED" and [b["m"] for b in sh["bands"]] == [-1, 0, 1]
    baked = [photonlm.read_lightmap_exr(tmp_path / "one" / bands[k]).rgb for k in (1, 2, 3)]
    for b, want in zip(sh["bands"], (baked[1], -baked[0], baked[2])):
        image = doc["images"][doc["textures"][b["texture"]]["source"]]
        px = np.asarray(Image.open(io.BytesIO(view(doc, binary, image["bufferView"]))).convert("RGBA"),
                        np.float64)[::-1] / 255.0
        got = (2.0 * px[..., :3] - 1.0) * px[..., 3:4] * b["range"]
        assert np.all(np.abs(got - want) <= px[..., 3:4] * b["range"] / 255.0 * (1 + 1e-6) + 1e-7 * b["range"])
    # --directional off overrides the file; a bad value is refused naming the option.
    cli("bake", path, "--directional", "off", "-o", tmp_path / "plain")
    assert sorted(os.listdir(tmp_path / "plain")) == ["floor_lightmap.exr", "report.json"]
    r = subprocess.run([CLI, "bake", str(path), "--directional", "yes", "-o", str(tmp_path / "bad")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode != 0 and "--directional" in r.stderr
    scene["settings"]["directional"] = 1
    path.write_text(json.dumps(scene))
    r = subprocess.run([CLI, "bake", str(path), "-o", str(tmp_path / "bad2")], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 1 and "scene.settings.directional" in r.stderr, r.stderr
