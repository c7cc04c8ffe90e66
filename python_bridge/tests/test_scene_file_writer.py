"""photonlm.scene_file.SceneFileWriter: the same calls as photonlm.Scene, written to a scene file
and baked by `photonlm bake`, give the lightmaps the bridge bakes in memory, bit for bit (the
file holds the bridge's float32 values exactly; results depend on the seed only). Inline and OBJ
sidecar meshes alike, shading normals and smooth meshes, and subdivision cages (written as cages,
refined by the CLI). Unsupported
calls and bad input fail with a message naming the call or the mesh."""
import json
import os
import subprocess

import numpy as np
import pytest

import photonlm
from photonlm.scene_file import SceneFileUnsupported, SceneFileWriter

import scenes
from test_cli import CLI
from test_subdiv import CUBE, FACES, cube_uv
from test_texture import checker, write_ppm

pytestmark = pytest.mark.skipif(CLI is None or not os.access(CLI, os.X_OK), reason="the photonlm CLI was not found")


def exr_bytes(path):
    """An EXR file's bytes with the value of its capDate header attribute (the time of writing, to
    the second) blanked: two writes of the same lightmap straddling a second differ only there."""
    data = bytearray(open(path, "rb").read())
    key = b"capDate\x00string\x00"
    i = data.find(key)
    if i >= 0:
        start = i + len(key) + 4
        n = int.from_bytes(data[start - 4:start], "little")
        data[start:start + n] = b"#" * n
    return bytes(data)


def build(s, texture):
    """A lit room: a floor with a checker albedo texture, a tilted quad with two materials, a CSG
    sphere carried by a mesh, an OL group (backup), a spot and a sun, a world colour. Returns the
    lightmapped mesh ids."""
    grey = s.add_material(0.6, name="grey")
    s.set_material_texture(grey, "albedo", texture, "srgb")
    red = s.add_material((0.8, 0.1, 0.1), name="red paint")  # a space: OBJ needs a token name
    s.add_material_lobe(red, "fresnel", (0.9, 0.6, 0.3), roughness=0.2, weight=0.8)
    s.add_material_lobe(red, "transparent", 0.5, weight=0.2)
    s.add_material(0.3, emission=(0.5, 0.5, 0.4), name="lamp")
    pos, tri, uv = scenes.plane(2.0, 0.0)
    floor = s.add_mesh("floor", pos, tri, lightmap_uv=uv, material_ids=[grey, grey], resolution=16)
    s.set_mesh_texture_uv(floor, uv * np.float32(2.0))
    rng = np.random.default_rng(3)
    tilt = (pos * np.float32(0.3) + np.float32([0.1, 0.2, 0.7])).astype(np.float32)
    tilt[:, 2] += rng.random(4, dtype=np.float32) * np.float32(0.1)
    quad = s.add_mesh("tilted/quad", tilt, tri, lightmap_uv=uv, material_ids=[grey, red], resolution=(8, 4))
    s.set_mesh_normals(quad, (rng.random((2, 3, 3)) - np.float32(0.5)) * np.float32(0.4) + np.float32([0, 0, 1]))
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
    # Meshes with texture UVs or normals stay inline (the reader takes them for inline meshes only).
    assert [("obj" in m) for m in doc["meshes"]] == [False, False, threshold == 0]
    assert len(doc["meshes"][1]["normals"]) == 18
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
                cli_bytes = exr_bytes(out / report["meshes"][k]["file"])
                assert cli_bytes == exr_bytes(mine), report["meshes"][k]["name"]


def build_cages(s):
    """Two Catmull-Clark cubes (add_subdiv_mesh) on a lit floor: "blob" (level 3, a lightmap, two
    materials by face, two creases of 1.0 and 0.5) and "pebble" (level 2, geometry only, in an OL
    group). Returns (lightmapped mesh ids, OL group id)."""
    grey = s.add_material(0.6, name="grey")
    red = s.add_material((0.8, 0.2, 0.1), name="red")
    pos, tri, uv = scenes.plane(2.0, 0.0)
    floor = s.add_mesh("floor", pos, tri, lightmap_uv=uv, resolution=16)
    cage = CUBE * np.float32(0.3) + np.float32([0.1, -0.2, 0.45])
    blob = s.add_subdiv_mesh("blob", cage, np.full(6, 4), FACES.ravel(), 3, lightmap_uv=cube_uv(),
                             material_ids=[grey, red, grey, red, grey, grey], crease_edges=[[0, 4], [4, 6]],
                             crease_weights=[1.0, 0.5], resolution=(24, 16))
    s.set_mesh_smooth(blob)
    g = s.add_ol_group("pebbles", 8)
    pebble = s.add_subdiv_mesh("pebble", CUBE * np.float32(0.2) + np.float32([-0.9, 0.7, 0.25]), np.full(6, 4),
                               FACES.ravel(), 2, material_ids=np.full(6, red))
    s.set_mesh_ol_group(pebble, g)
    s.add_light("SPOT", name="spot", power=150.0, matrix=scenes.translation(0.3, 0.2, 1.8), spot_size=1.4,
                radius=0.05)
    s.add_light("SUN", power=2.0, angle=0.05, matrix=scenes.rotation_x(0.5))
    s.set_world((0.02, 0.03, 0.05))
    return [floor, blob], g


def test_file_bake_of_subdivision_cages_equals_bridge_bake(tmp_path):
    """The writer records cages (not refined meshes): the CLI refines and bakes them into the same
    EXR bytes as the bridge's in-memory bake with the same seed (lightmaps and the OL)."""
    w = SceneFileWriter(obj_threshold=0)  # every triangle mesh to OBJ; cages stay inline
    ids, g = build_cages(w)
    w.set_settings(**SETTINGS)
    path = w.write(str(tmp_path / "scene.json"))
    doc = json.loads(open(path).read())
    floor, blob, pebble = doc["meshes"]
    assert "obj" in floor and "obj" not in blob and "obj" not in pebble
    assert blob["subdivision"] == {"level": 3, "face_sizes": [4] * 6, "creases": [[0, 4, 1.0], [4, 6, 0.5]]}
    assert blob["indices"] == FACES.ravel().tolist() and blob["materials"] == [0, 1, 0, 1, 0, 0]
    assert len(blob["lightmap_uv"]) == 48 and blob["lightmap_resolution"] == [24, 16] and blob["smooth"] is True
    assert pebble["subdivision"] == {"level": 2, "face_sizes": [4] * 6} and pebble["material"] == 1
    assert "lightmap_uv" not in pebble and "lightmap_resolution" not in pebble and pebble["ol_group"] == 0
    out = tmp_path / "out"
    r = subprocess.run([CLI, "bake", path, "-o", str(out), "--threads", "1"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    report = json.loads((out / "report.json").read_text())
    files, groups = w.output_files()
    assert [m["file"] for m in report["meshes"]] == list(files.values()) == ["floor_lightmap.exr",
                                                                              "blob_lightmap.exr"]
    with photonlm.Scene() as scene:
        assert build_cages(scene) == (ids, g)
        with scene.bake(**SETTINGS) as result:
            assert result.lightmap(ids[1]).rgb.max() > 0  # the blob is lit (a dark bake would prove little)
            assert result.ol_stats(g)["hits"] > 0
            for i, f in zip(ids, files.values()):
                mine = tmp_path / ("bridge_" + f)
                result.write_exr(i, str(mine))
                assert exr_bytes(out / f) == exr_bytes(mine), f
            mine = tmp_path / "bridge_ol.exr"
            result.write_ol_exr(g, str(mine))
            assert exr_bytes(out / groups["pebbles"]) == exr_bytes(mine)


def test_bad_cages_are_named():
    w = SceneFileWriter()
    w.add_material(0.5)
    faces = FACES.ravel()
    assert hasattr(w, "add_subdiv_mesh")
    with pytest.raises(ValueError, match=r"face_indices of mesh 'c' must hold sum\(face_sizes\) = 24"):
        w.add_subdiv_mesh("c", CUBE, np.full(6, 4), faces[:-1], 2)
    with pytest.raises(ValueError, match=r"mesh 'c': subdivision level 0 is not in \[1, 10\]"):
        w.add_subdiv_mesh("c", CUBE, np.full(6, 4), faces, 0)
    bad = faces.copy()
    bad[14] = 9
    with pytest.raises(ValueError, match=r"mesh 'c': cage face 3 \(face_indices\[14\]\) uses vertex 9"):
        w.add_subdiv_mesh("c", CUBE, np.full(6, 4), bad, 2)
    with pytest.raises(ValueError, match="mesh 'c': crease 1 names the edge 0-7, which no cage face has"):
        w.add_subdiv_mesh("c", CUBE, np.full(6, 4), faces, 2, crease_edges=[[0, 4], [0, 7]],
                          crease_weights=[1.0, 1.0])
    with pytest.raises(ValueError, match=r"mesh 'c': crease_weights\[0\] = 1.5 is not in \[0, 1\]"):
        w.add_subdiv_mesh("c", CUBE, np.full(6, 4), faces, 2, crease_edges=[[0, 4]], crease_weights=[1.5])
    with pytest.raises(ValueError, match="mesh 'c' has a lightmap .* but no lightmap_uv"):
        w.add_subdiv_mesh("c", CUBE, np.full(6, 4), faces, 2, resolution=8)
    with pytest.raises(ValueError, match=r"mesh 'c': cage face 2 uses material 1, out of range \(1 materials\)"):
        w.add_subdiv_mesh("c", CUBE, np.full(6, 4), faces, 2, material_ids=[0, 0, 1, 0, 0, 0])
    six = np.concatenate([CUBE + np.float32(3 * k) for k in range(6)])  # 144 corners: 2 x 144 x 4^9 > 2^25
    with pytest.raises(ValueError, match="mesh 'c': level 10 makes 75497472 triangles from 144 face corners"):
        w.add_subdiv_mesh("c", six, np.full(36, 4), np.concatenate([faces + 8 * k for k in range(6)]), 10)
    assert w.meshes == []
    c = w.add_subdiv_mesh("c", CUBE, np.full(6, 4), faces, 2, lightmap_uv=cube_uv(), resolution=8)
    with pytest.raises(SceneFileUnsupported, match="mesh 'c' is a subdivision cage: .* no texture_uv"):
        w.set_mesh_texture_uv(c, np.zeros((96, 3, 2), np.float32))


def test_unsupported_and_bad_calls_are_named(tmp_path):
    w = SceneFileWriter()
    with pytest.raises(SceneFileUnsupported, match="L-system 'tree'"):
        w.add_lsystem("tree", "axiom: F")
    with pytest.raises(SceneFileUnsupported, match=r"photonlm.Scene.add_magic"):
        w.add_magic("x")
    assert not hasattr(w, "add_magic")  # callers can test for support
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
