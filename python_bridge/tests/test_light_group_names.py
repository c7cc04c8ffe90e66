"""Light groups outside Blender: the add-on's plan and name check (addon/photonlm_blender/export/
lightgroups.py, pure Python) agree with the engine, and SceneFileWriter records light groups so that
`photonlm bake` gives each lightmap the same layers as a bridge bake."""
import importlib.util
import json
import os
import subprocess
import types

import numpy as np
import pytest

import photonlm
from photonlm.scene_file import SceneFileWriter

import scenes
from test_cli import CLI

_PATH = os.path.join(os.path.dirname(__file__), "..", "..", "addon", "photonlm_blender", "export", "lightgroups.py")
_spec = importlib.util.spec_from_file_location("lightgroups", _PATH)
lightgroups = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(lightgroups)


@pytest.mark.parametrize("name", ["day", "Night_2", "a-b", "x" * 64, "default", "", "x" * 65, "two words",
                                  "caf\u00e9", "a.b"])
def test_name_check_agrees_with_the_engine(name):
    why = lightgroups.name_problem(name)
    with photonlm.Scene() as s:
        try:
            s.add_light_group(name)
            taken = True
        except photonlm.PhotonlmError:
            taken = False
    assert (why == "") == taken, (name, why)


def test_check_names_names_the_group():
    lightgroups.check_names(["day", "night"])
    with pytest.raises(ValueError, match="light group 'default' cannot be baked"):
        lightgroups.check_names(["day", "default"])


def _view_layer(*names):
    return types.SimpleNamespace(lightgroups=[types.SimpleNamespace(name=n) for n in names])


def _emitter(group):
    return types.SimpleNamespace(lightgroup=group)


def test_plan_declares_the_named_groups_in_view_layer_order():
    vl = _view_layer("night", "day", "unused")
    assert lightgroups.plan(vl, [_emitter("day"), _emitter(""), _emitter("night"), _emitter("other")]) == \
        ["night", "day"]
    # No Light Groups, or none named: bake as without groups.
    assert lightgroups.plan(_view_layer(), [_emitter("day")]) == []
    assert lightgroups.plan(vl, [_emitter(""), _emitter("other")]) == []
    assert lightgroups.plan(types.SimpleNamespace(), [_emitter("day")]) == []  # a Blender without Light Groups


def test_group_ids_put_unknown_names_in_the_default_group():
    ids = lightgroups.GroupIds(["day", "night"], [1, 2])
    assert bool(ids) and not lightgroups.GroupIds([], [])
    assert [ids.of(_emitter(g)) for g in ("day", "night", "", "other")] == [1, 2, 0, 0]
    assert ids.of(None) == 0


def build(s):
    """A floor lit by a sun ("day"), a spot ("night"), an emissive panel ("night") and the world ("day")."""
    grey = s.add_material(0.6, name="grey")
    lamp = s.add_material(0.3, emission=(2.0, 2.0, 1.8), name="lamp")
    day, night = s.add_light_group("day"), s.add_light_group("night")
    pos, tri, uv = scenes.plane(2.0, 0.0)
    floor = s.add_mesh("floor", pos, tri, lightmap_uv=uv, material_ids=[grey, grey], resolution=16)
    panel = s.add_mesh("panel", pos * np.float32(0.2) + np.float32([0.0, 0.0, 1.5]), tri[:, ::-1].copy(),
                       material_ids=[lamp, lamp])
    s.set_light_group(night, mesh=panel)
    sun = s.add_light("SUN", power=2.0, angle=0.05, matrix=scenes.rotation_x(0.4))
    spot = s.add_light("SPOT", name="spot", power=100.0, matrix=scenes.translation(0.3, 0.0, 1.8), spot_size=1.2)
    s.set_light_group(day, light=sun)
    s.set_light_group(night, light=spot)
    s.set_world((0.02, 0.03, 0.05))
    s.set_light_group(day, world=True)
    return floor


SETTINGS = dict(photons=40_000, seed=3, direct_samples=4, max_bounces=8)


def test_writer_records_light_groups():
    w = SceneFileWriter()
    build(w)
    doc = w.to_json()
    assert doc["light_groups"] == ["day", "night"]
    assert [m.get("group") for m in doc["meshes"]] == [None, "night"]
    assert [l.get("group") for l in doc["lights"]] == ["day", "night"]
    assert doc["world"]["group"] == "day"
    for bad in ("default", "day", "two words"):
        with pytest.raises(ValueError, match="light group '%s'" % bad):
            w.add_light_group(bad)
    with pytest.raises(ValueError, match="light group 3 does not exist"):
        w.set_light_group(3, light=0)
    w.set_light_group(0, light=0)  # back to the default group
    assert "group" not in w.to_json()["lights"][0]


@pytest.mark.skipif(CLI is None or not os.access(CLI, os.X_OK), reason="the photonlm CLI was not found")
def test_file_bake_has_the_bridge_bakes_layers(tmp_path):
    with photonlm.Scene() as s:
        floor = build(s)
        with s.bake(**SETTINGS) as result:
            layers = result.layers
            ref = [result.lightmap_layer(floor, k)[0].copy() for k in range(len(layers))]
    assert layers == ["day", "night"]
    w = SceneFileWriter()
    build(w)
    w.set_settings(**SETTINGS)
    path = w.write(str(tmp_path / "scene.json"))
    out = tmp_path / "out"
    r = subprocess.run([CLI, "bake", path, "-o", str(out), "--threads", "1"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    report = json.loads((out / "report.json").read_text())
    assert [g["name"] for g in report["light_groups"]] == layers
    floor_report = next(m for m in report["meshes"] if m["name"] == "floor")
    assert [l["group"] for l in floor_report["layers"]] == layers
    for k, layer in enumerate(floor_report["layers"]):
        got = photonlm.read_lightmap_exr(str(out / layer["file"])).rgb
        np.testing.assert_allclose(got, ref[k], rtol=1e-5, atol=1e-7)
