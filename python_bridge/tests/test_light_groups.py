"""Light groups through the bridge and the CLI: one bake, a layer per group, the layers adding up to the
lightmap, each layer a bake of its group's lights alone within its error; files per layer."""
import json
import os
import subprocess

import numpy as np
import pytest

import photonlm
from scenes import plane, translation
from test_cli import CLI, QUAD


def lamp_room(scene, groups=True, lamps=(0, 1)):
    """A floor under two point lamps of different colours and a dim world; the lamps in groups
    "warm" and "cool" (the world in the default group)."""
    scene.add_material(albedo=0.7)
    pos, tri, uv = plane(2.0)
    floor = scene.add_mesh("floor", pos, tri, uv, resolution=24)
    scene.set_world((0.05, 0.05, 0.05))
    ids = [scene.add_light_group("warm"), scene.add_light_group("cool")] if groups else None
    for k in lamps:
        x, color = ((-1.0, (1.0, 0.6, 0.3)), (1.0, (0.3, 0.6, 1.0)))[k]
        light = scene.add_light("POINT", power=150.0, color=color, matrix=translation(x, 0.0, 1.2))
        if groups:
            scene.set_light_group(ids[k], light=light)
    return floor


def test_layers_add_up_and_match_their_lights_alone():
    settings = dict(photons=200000, direct_samples=64, seed=4)
    with photonlm.Scene() as scene:
        floor = lamp_room(scene)
        with scene.bake(**settings) as r:
            assert r.layers == ["default", "warm", "cool"]
            whole = r.lightmap(floor).rgb
            layers = [r.lightmap_layer(floor, name) for name in r.layers]
            errors = [r.layer_error(k) for k in range(3)]
    total = sum(rgb for rgb, _ in layers)
    assert np.allclose(total, whole, rtol=1e-4, atol=1e-6)
    assert all(0.0 < e < 0.2 for e in errors), errors
    for k, name in ((0, "warm"), (1, "cool")):
        with photonlm.Scene() as scene:
            lamp_room(scene, groups=False, lamps=(k,))
            scene.set_world((0.0, 0.0, 0.0))
            with scene.bake(**settings) as r:
                alone = r.lightmap(floor).rgb
        rgb, err = layers[1 + k]
        # Per channel over the floor: within 2 % of the lamp's own bake, and texel by texel within 4 x
        # the layer's reported error (plus the lone bake's noise, of the same size).
        assert np.allclose(rgb.mean(axis=(0, 1)), alone.mean(axis=(0, 1)), rtol=0.02), name
        diff = np.abs(rgb.mean(axis=2) - alone.mean(axis=2))
        assert np.mean(diff <= 4.0 * np.sqrt(2.0) * err + 1e-6) > 0.95, name


def test_bad_groups_raise_naming_the_problem():
    with photonlm.Scene() as scene:
        lamp_room(scene, groups=False)
        with pytest.raises(photonlm.PhotonlmError, match="default group's name"):
            scene.add_light_group("default")
        with pytest.raises(ValueError, match="exactly one"):
            scene.set_light_group(0, light=0, world=True)
        with pytest.raises(photonlm.PhotonlmError, match="light group 3 does not exist"):
            scene.set_light_group(3, mesh=0)
        with scene.bake(photons=1000, direct_samples=1) as r:
            assert r.layers == []
            with pytest.raises(photonlm.PhotonlmError, match="no light-group layer 'warm'"):
                r.lightmap_layer(0, "warm")


@pytest.mark.skipif(CLI is None or not os.access(CLI, os.X_OK), reason="the photonlm CLI was not found")
def test_cli_writes_a_file_per_layer(tmp_path):
    scene = {
        "version": 1,
        "light_groups": ["day", "night"],
        "materials": [{"name": "grey", "albedo": 0.6}],
        "meshes": [dict(QUAD, name="floor", material="grey", lightmap_resolution=8)],
        "lights": [{"type": "SUN", "power": 3, "group": "day"},
                   {"type": "POINT", "power": 100, "location": [0, 0, 1], "group": "night"}],
        "world": {"radiance": [0.2, 0.3, 0.5], "group": "day"},
        "settings": {"photon_count": 20000, "direct_samples": 4, "seed": 1},
    }
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    out = tmp_path / "out"
    r = subprocess.run([CLI, "bake", str(path), "-o", str(out)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert sorted(os.listdir(out)) == ["floor_lightmap.day.exr", "floor_lightmap.exr", "floor_lightmap.night.exr",
                                       "report.json"]
    report = json.loads((out / "report.json").read_text())
    assert [g["name"] for g in report["light_groups"]] == ["day", "night"]
    assert report["meshes"][0]["layers"] == [{"group": "day", "file": "floor_lightmap.day.exr"},
                                             {"group": "night", "file": "floor_lightmap.night.exr"}]
    whole = photonlm.read_lightmap_exr(out / "floor_lightmap.exr").rgb
    day = photonlm.read_lightmap_exr(out / "floor_lightmap.day.exr").rgb
    night = photonlm.read_lightmap_exr(out / "floor_lightmap.night.exr").rgb
    assert np.allclose(day + night, whole, rtol=1e-4, atol=1e-6)
    assert day.mean() > 0 and night.mean() > 0

    scene["lights"][1]["group"] = "evening"
    path.write_text(json.dumps(scene))
    r = subprocess.run([CLI, "bake", str(path), "-o", str(tmp_path / "bad")], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 1
    assert "scene.lights[1].group" in r.stderr and "evening" in r.stderr


@pytest.mark.skipif(CLI is None or not os.access(CLI, os.X_OK), reason="the photonlm CLI was not found")
def test_cli_merge_writes_the_layers_of_one_machine(tmp_path):
    scene = {
        "version": 1,
        "light_groups": ["sun", "lamp"],
        "materials": [{"name": "grey", "albedo": 0.6}],
        "meshes": [dict(QUAD, name="floor", material="grey", lightmap_resolution=8)],
        "lights": [{"type": "SUN", "power": 3, "group": "sun"},
                   {"type": "POINT", "power": 100, "location": [0, 0, 1], "group": "lamp"}],
        "settings": {"photon_count": 40000, "direct_samples": 4, "seed": 2},
    }
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))

    def cli(*args):
        r = subprocess.run([CLI] + [str(a) for a in args], capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
    cli("bake", path, "-o", tmp_path / "one")
    for k in (1, 2):
        cli("bake", path, "--shard", "%d/2" % k, "-o", tmp_path / "parts")
    cli("merge", tmp_path / "parts", "--scene", path, "-o", tmp_path / "merged")
    for name in ("floor_lightmap.exr", "floor_lightmap.sun.exr", "floor_lightmap.lamp.exr"):
        assert (tmp_path / "one" / name).read_bytes() == (tmp_path / "merged" / name).read_bytes(), name
