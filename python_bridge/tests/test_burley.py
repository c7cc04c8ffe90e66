"""Burley diffuse (Blender 3.x's Principled BSDF) through the bridge and scene files: a floor under a
sun at grazing bakes what Cycles 3.4 bakes for a Burley surface (the light weighted by
1 - F / 2 + r (1 + cos) F, F = (1 - cos)^5), the scene-file key, and bad values refused."""
import json
import math
import subprocess

import numpy as np
import pytest

import photonlm
from photonlm.scene_file import SceneFileWriter
from scenes import plane, rotation_x
from test_cli import CLI

COS = math.cos(1.4)  # the sun 80 degrees from the zenith


def build(scene, model=None, roughness=0.0):
    m = scene.add_material(albedo=0.5)
    if model is not None:
        scene.set_material_diffuse(m, model, roughness)
    pos, tri, uv = plane(half=1.0)
    floor = scene.add_mesh("floor", pos, tri, uv, resolution=4)
    scene.add_light("SUN", power=1.0, angle=0.0, matrix=rotation_x(1.4))
    return floor


SETTINGS = dict(photons=1000, max_bounces=0, direct_samples=64, seed=3)


def floor_mean(model=None, roughness=0.0):
    with photonlm.Scene() as scene:
        floor = build(scene, model, roughness)
        with scene.bake(**SETTINGS) as result:
            return float(result.lightmap(floor).rgb.mean())


def test_burley_weighs_grazing_light_as_cycles_3_4_bakes_it():
    lambert = floor_mean()
    assert lambert == pytest.approx(COS / math.pi, rel=1e-3)
    assert floor_mean("lambert") == lambert
    f = (1.0 - COS) ** 5
    for r in (0.0, 0.5, 1.0):
        assert floor_mean("burley", r) == pytest.approx(lambert * (1.0 - 0.5 * f + r * (1.0 + COS) * f), rel=2e-3)


def test_bad_model_and_roughness_are_refused():
    with photonlm.Scene() as scene:
        m = scene.add_material(albedo=0.5)
        with pytest.raises(ValueError):
            scene.set_material_diffuse(m, "oren-nayar", 0.5)
        with pytest.raises(photonlm.PhotonlmError, match="roughness"):
            scene.set_material_diffuse(m, "burley", 1.5)
    w = SceneFileWriter()
    m = w.add_material(0.5)
    with pytest.raises(ValueError):
        w.set_material_diffuse(m, "burley", -0.1)


def test_scene_file_key_bakes_as_the_bridge(tmp_path):
    w = SceneFileWriter()
    build(w, "burley", 0.8)
    w.set_settings(**SETTINGS)
    path = w.write(str(tmp_path / "scene.json"))
    assert json.loads(open(path).read())["materials"][0]["burley_roughness"] == pytest.approx(0.8)
    out = tmp_path / "out"
    r = subprocess.run([CLI, "bake", path, "-o", str(out), "--threads", "1"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    report = json.loads((out / "report.json").read_text())
    assert np.mean(report["meshes"][0]["mean"]) == pytest.approx(floor_mean("burley", 0.8), rel=1e-5)
