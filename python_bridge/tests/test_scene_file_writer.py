"""photonlm.scene_file.SceneFileWriter: the same calls as photonlm.Scene, written to a scene file
and baked by `photonlm bake`, give the lightmaps the bridge bakes in memory, bit for bit (the
file holds the bridge's float32 values exactly; results depend on the seed only). Inline and OBJ
sidecar meshes alike. Unsupported calls and bad input fail with a message naming the call or
the mesh."""
import json
import os
import subprocess

import numpy as np
import pytest

import photonlm
from photonlm.scene_file import SceneFileUnsupported, SceneFileWriter

import scenes
from test_cli import CLI
from test_texture import checker, write_ppm

pytestmark = pytest.mark.skipif(CLI is None or not os.access(CLI, os.X_OK), reason="the photonlm CLI was not found")


def build(s, texture):
    """A lit room: a floor with a checker albedo texture, a tilted quad with two materials, a CSG
    sphere carried by a mesh, an OL group (backup), a spot and a sun, a world colour. Returns the
    lightmapped mesh ids."""
    grey = s.add_material(0.6, name="grey")
    s.set_material_texture(grey, "albedo", texture, "srgb")
    red = s.add_material((0.8, 0.1, 0.1), name="red paint")  # a space: OBJ needs a token name
    s.add_material(0.3, emission=(0.5, 0.5, 0.4), name="lamp")
    pos, tri, uv = scenes.plane(2.0, 0.0)
    floor = s.add_mesh("floor", pos, tri, lightmap_uv=uv, material_ids=[grey, grey], resolution=16)
    s.set_mesh_texture_uv(floor, uv * np.float32(2.0))
    rng = np.random.default_rng(3)
    tilt = (pos * np.float32(0.3) + np.float32([0.1, 0.2, 0.7])).astype(np.float32)
    tilt[:, 2] += rng.random(4, dtype=np.float32) * np.float32(0.1)
    quad = s.add_mesh("tilted/quad", tilt, tri, lightmap_uv=uv, material_ids=[grey, red], resolution=(8, 4))
    g = s.add_ol_group("props", 8)
    s.set_ol_group_backup(g, True)
    s.set_mesh_ol_group(quad, g)
    carrier = s.add_mesh("ball", pos * np.float32(0.2) + np.float32([0.8, 0.8, 0.3]), tri, lightmap_uv=uv,
                         resolution=8)
    m = np.eye(4)
    m[:3, 3] = (0.8, 0.8, 0.3)
    m[:3, :3] *= 0.25
    csg = s.add_csg("ball", [dict(shape="SPHERE", matrix=m, material=red),
                             dict(shape="BOX", matrix=m * 0.8 + np.diag([0, 0, 0, 0.2]), material=grey)],
                    ("DIFFERENCE", 0, 1))
    s.set_csg_carrier(csg, carrier)
    s.add_light("SPOT", name="spot", power=200.0, matrix=scenes.translation(0.0, 0.0, 1.8), spot_size=1.2,
                spot_blend=0.2, radius=0.05)
    s.add_light("SUN", power=2.0, angle=0.05, matrix=scenes.rotation_x(0.4))
    s.set_world((0.02, 0.03, 0.05))
    return [floor, quad, carrier]


SETTINGS = dict(photons=40_000, seed=9, direct_samples=4, max_bounces=16, filter_radius=1, texel_value="AREA")


@pytest.mark.parametrize("threshold", [10_000, 0], ids=["inline", "obj"])
def test_file_bake_equals_bridge_bake(tmp_path, threshold):
    tex = str(write_ppm(tmp_path / "checker.ppm", checker(32, (200, 40, 40), (40, 200, 90), 8)))
    with photonlm.Scene() as scene:
        ids = build(scene, tex)
        with scene.bake(**SETTINGS) as result:
            ref = [result.lightmap(i).rgb.copy() for i in ids]
    w = SceneFileWriter(obj_threshold=threshold)
    build(w, tex)
    w.set_settings(**SETTINGS)
    path = w.write(str(tmp_path / "scene.json"))
    doc = json.loads(open(path).read())
    # Meshes with texture UVs stay inline (the reader takes texture_uv for inline meshes only).
    assert [("obj" in m) for m in doc["meshes"]] == [False] + [threshold == 0] * 2
    assert doc["materials"][0]["albedo_texture"] == {"path": "scene_textures/checker.ppm", "colorspace": "srgb"}
    assert (tmp_path / "scene_textures" / "checker.ppm").read_bytes() == open(tex, "rb").read()
    assert doc["ol_groups"][0]["backup"] is True and doc["csg"][0]["carrier"] == 2
    out = tmp_path / "out"
    r = subprocess.run([CLI, "bake", path, "-o", str(out), "--threads", "1"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    report = json.loads((out / "report.json").read_text())
    files, _ = w.output_files()
    assert [m["file"] for m in report["meshes"]] == list(files.values())  # the writer predicts the names
    assert files["tilted/quad"] == "tilted_quad_lightmap.exr"
    # The report's per-mesh mean over covered texels equals the bridge bake's, to float rounding of a sum.
    with photonlm.Scene() as scene:
        ids = build(scene, tex)
        with scene.bake(**SETTINGS) as result:
            for k, i in enumerate(ids):
                lm = result.lightmap(i)
                assert np.array_equal(lm.rgb, ref[k])  # the bridge itself is deterministic
                c = lm.coverage
                mean = (lm.rgb * c[..., None]).reshape(-1, 3).sum(0) / c.sum()
                np.testing.assert_allclose(report["meshes"][k]["mean"], mean, rtol=1e-6, atol=0)
            # Bit for bit: the CLI's EXR against the bridge's own EXR writer on the same result.
            for k, i in enumerate(ids):
                mine = tmp_path / ("bridge_%d.exr" % k)
                result.write_exr(i, str(mine))
                cli_bytes = (out / report["meshes"][k]["file"]).read_bytes()
                assert cli_bytes == mine.read_bytes(), report["meshes"][k]["name"]


def test_unsupported_and_bad_calls_are_named(tmp_path):
    w = SceneFileWriter()
    with pytest.raises(SceneFileUnsupported, match="L-system 'tree'"):
        w.add_lsystem("tree", "axiom: F")
    with pytest.raises(SceneFileUnsupported, match=r"photonlm.Scene.add_subdiv_mesh"):
        w.add_subdiv_mesh("cage", None, None)
    assert not hasattr(w, "add_subdiv_mesh")  # callers can test for support
    pos, tri, uv = scenes.plane()
    with pytest.raises(ValueError, match=r"mesh 'q': triangles\[1, 2\] = 7 is out of range \(4 vertices\)"):
        w.add_mesh("q", pos, np.array([[0, 1, 2], [0, 2, 7]]), lightmap_uv=uv, resolution=4)
    bad = pos.copy()
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match=r"mesh 'q' positions\[2, 1\] = nan is not finite"):
        w.add_mesh("q", bad, tri)
    with pytest.raises(ValueError, match="has a lightmap .* but no lightmap_uv"):
        w.add_mesh("q", pos, tri, resolution=4)
    with pytest.raises(ValueError, match="unknown bake setting 'photon'"):
        w.set_settings(photon=5)
