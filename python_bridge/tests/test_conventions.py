"""Cycles versions' conventions through the bridge: the setting, the scene-file key, and a
direct-light bake of an area light and a spot under Cycles 3.4's and Cycles 4's conventions."""
import json
import math

import numpy as np
import pytest

import photonlm
from photonlm.scene_file import SceneFileWriter
from scenes import plane, translation


def test_default_and_setting():
    with photonlm.Scene() as scene:
        assert scene.conventions == "cycles-3.4"
        scene.set_conventions("cycles-4")
        assert scene.conventions == "cycles-4"
    with photonlm.Scene(conventions="cycles-4") as scene:
        assert scene.conventions == "cycles-4"
    with pytest.raises(ValueError):
        photonlm.Scene(conventions="cycles-9")


def test_scene_file_key(tmp_path):
    w = SceneFileWriter()
    assert "conventions" not in w.to_json()
    w.set_conventions("cycles-4")
    path = tmp_path / "scene.json"
    w.write(str(path))
    assert json.loads(path.read_text())["conventions"] == "cycles-4"
    with pytest.raises(ValueError):
        w.set_conventions("blender")


def direct_bake(conventions, light, **fields):
    """Floor lit by one light 1.5 m up, direct light only (no photons): its mean texel."""
    with photonlm.Scene(conventions=conventions) as scene:
        scene.add_material(albedo=0.0)
        pos, tri, uv = plane(half=1.0)
        floor = scene.add_mesh("floor", pos, tri, uv, resolution=8)
        scene.add_light(light, power=100.0, matrix=translation(0, 0, 1.5), **fields)
        with scene.bake(photons=1000, max_bounces=0, direct_samples=256, seed=3) as result:
            return float(result.lightmap(floor).rgb.mean())


def test_area_light_is_4_over_pi_brighter_under_cycles_4():
    for shape in ("AREA_RECT", "AREA_DISK"):
        ratio = direct_bake("cycles-3.4", shape, size=0.5) / direct_bake("cycles-4", shape, size=0.5)
        assert ratio == pytest.approx(math.pi / 4, rel=1e-3), shape


def test_spot_without_the_cosine_under_cycles_4():
    a = direct_bake("cycles-3.4", "SPOT", spot_size=math.radians(120), spot_blend=0.0, radius=0.0)
    b = direct_bake("cycles-4", "SPOT", spot_size=math.radians(120), spot_blend=0.0, radius=0.0)
    assert a < b  # the cos factor only dims
    p = direct_bake("cycles-4", "POINT", radius=0.0)
    # The floor (half side 1 m, 1.5 m below) lies inside the 120-degree cone: the spot is the point light.
    assert b == pytest.approx(p, rel=1e-4)
