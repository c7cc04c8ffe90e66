"""Environment maps through the bridge (Scene.set_world_map, set_world_map_file) and the scene file
writer: a two-tone map (upper hemisphere a, lower b) lights an up-facing plane with a and a
down-facing one with b (the truth, not the engine); the rotation turns it; bad pixels are named by
row and column; a file bake of the writer's scene equals the bridge's in-memory bake bit for bit,
for a map given as pixels (written as a PFM) and as a file (copied)."""
import json
import os
import subprocess

import numpy as np
import pytest

import photonlm
from photonlm.scene_file import SceneFileWriter

import scenes
from test_cli import CLI
from test_scene_file_writer import exr_bytes

A = np.float32([1.0, 0.8, 0.6])
B = np.float32([0.2, 0.25, 0.3])


def two_tone(w=64, h=32):
    rgb = np.empty((h, w, 3), np.float32)
    rgb[: h // 2] = A
    rgb[h // 2:] = B
    return rgb


def plane_mean(facing_down, rotation=None, strength=1.0, rgb=None):
    pos, tri, uv = scenes.plane(0.5, 0.0)
    if facing_down:
        tri = tri[:, ::-1].copy()
        uv = uv[:, ::-1].copy()
    with photonlm.Scene() as s:
        s.add_material(0.0)
        m = s.add_mesh("plane", pos, tri, lightmap_uv=uv, resolution=4)
        s.set_world_map(two_tone() if rgb is None else rgb, rotation=rotation, strength=strength)
        with s.bake(photons=10_000, direct_samples=64, texel_value="AREA") as r:
            lm = r.lightmap(m)
            return (lm.rgb * lm.coverage[..., None]).reshape(-1, 3).sum(0) / lm.coverage.sum()


def test_two_tone_map_lights_planes_by_the_hemisphere_they_see():
    np.testing.assert_allclose(plane_mean(False), A, rtol=0.01)
    np.testing.assert_allclose(plane_mean(True), B, rtol=0.01)
    np.testing.assert_allclose(plane_mean(False, strength=2.0), 2 * A, rtol=0.01)
    # Turned half a turn about X (map +Z -> world -Z): the planes swap.
    flip = np.diag([1.0, -1.0, -1.0])
    np.testing.assert_allclose(plane_mean(False, rotation=flip), B, rtol=0.01)
    np.testing.assert_allclose(plane_mean(True, rotation=flip.ravel()), A, rtol=0.01)


def test_bad_maps_are_refused_naming_what_is_wrong(tmp_path):
    rgb = two_tone(8, 4)
    rgb[2, 5, 1] = np.nan
    with photonlm.Scene() as s:
        with pytest.raises(photonlm.PhotonlmError, match="row 2, column 5"):
            s.set_world_map(rgb)
        with pytest.raises(ValueError, match=r"shape \(H, W, 3\)"):
            s.set_world_map(np.zeros((4, 8), np.float32))
        with pytest.raises(ValueError, match="3x3"):
            s.set_world_map(two_tone(8, 4), rotation=np.eye(4))
        with pytest.raises(photonlm.PhotonlmError, match="rotation"):
            s.set_world_map(two_tone(8, 4), rotation=np.diag([2.0, 1.0, 1.0]))
        with pytest.raises(photonlm.PhotonlmError, match="strength"):
            s.set_world_map(two_tone(8, 4), strength=-1.0)
        with pytest.raises(photonlm.PhotonlmError, match="nowhere.hdr"):
            s.set_world_map_file(str(tmp_path / "nowhere.hdr"))
    w = SceneFileWriter()
    with pytest.raises(ValueError, match="row 2, column 5"):
        w.set_world_map(rgb)
    with pytest.raises(ValueError, match="no such file"):
        w.set_world_map_file(str(tmp_path / "nowhere.hdr"))


def build(s, world):
    """A floor and a box under a sun-spotted two-tone map, turned about Z."""
    grey = s.add_material(0.6, name="grey")
    pos, tri, uv = scenes.plane(2.0, 0.0)
    floor = s.add_mesh("floor", pos, tri, lightmap_uv=uv, material_ids=[grey, grey], resolution=16)
    ids = [floor]
    for k, corners in enumerate(scenes.box_faces()):
        p = (corners[::-1] - np.float32(0.5)) * np.float32(0.8) + np.float32([0.2, -0.1, 0.4])
        ids.append(s.add_mesh("box%d" % k, p.astype(np.float32), scenes.QUAD_TRIANGLES,
                              lightmap_uv=scenes.QUAD_UV, resolution=4))
    c, sn = np.cos(0.7), np.sin(0.7)
    rotation = np.array([[c, -sn, 0], [sn, c, 0], [0, 0, 1]])
    world(s, rotation)
    return ids


SETTINGS = dict(photons=40_000, seed=5, direct_samples=4, max_bounces=16, filter_radius=1, texel_value="AREA")


def sky():
    rgb = two_tone(64, 32)
    rgb[6, 20] += 400.0  # a sun
    return rgb


@pytest.mark.skipif(CLI is None or not os.access(CLI, os.X_OK), reason="the photonlm CLI was not found")
@pytest.mark.parametrize("as_file", [False, True], ids=["pixels", "file"])
def test_file_bake_equals_bridge_bake(tmp_path, as_file):
    if as_file:  # a PFM written here: float32 exactly, rows bottom first
        path = tmp_path / "sky.pfm"
        h, w, _ = sky().shape
        path.write_bytes(b"PF\n%d %d\n-1.0\n" % (w, h) + np.ascontiguousarray(sky()[::-1]).astype("<f4").tobytes())

        def world(s, rotation):
            s.set_world_map_file(str(path), rotation=rotation, strength=1.5)
    else:
        def world(s, rotation):
            s.set_world_map(sky(), rotation=rotation, strength=1.5)
    w = SceneFileWriter()
    ids = build(w, world)
    w.set_settings(**SETTINGS)
    scene_path = w.write(str(tmp_path / "scene.json"))
    doc = json.loads(open(scene_path).read())
    assert doc["world"]["map"] == "scene_textures/" + ("sky.pfm" if as_file else "world_map.pfm")
    assert doc["world"]["strength"] == 1.5 and len(doc["world"]["rotation"]) == 9
    out = tmp_path / "out"
    r = subprocess.run([CLI, "bake", scene_path, "-o", str(out), "--threads", "1"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    files, _ = w.output_files()
    with photonlm.Scene() as scene:
        assert build(scene, world) == ids
        with scene.bake(**SETTINGS) as result:
            assert result.lightmap(ids[0]).rgb.max() > 0
            for i, f in zip(ids, files.values()):
                mine = tmp_path / ("bridge_" + f)
                result.write_exr(i, str(mine))
                assert exr_bytes(out / f) == exr_bytes(mine), f
