"""Lightmaps held by the caller (atlas pages) written and read back as lightmap EXRs: the same
channels as a baked lightmap's file, rows bottom first, bad input refused with a message."""
import numpy as np
import pytest

import photonlm
from scenes import plane


def test_write_read_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    rgb = rng.random((5, 7, 3), dtype=np.float32)
    err = rng.random((5, 7), dtype=np.float32)
    hits = rng.integers(0, 100, (5, 7)).astype(np.float32)
    rgb[0, 0] = (1.0, 2.0, 3.0)  # bottom-left texel: row 0 stays row 0
    path = tmp_path / "page.exr"
    photonlm.write_lightmap_exr(path, rgb, err, hits)
    lm = photonlm.read_lightmap_exr(path)
    assert np.array_equal(lm.rgb, rgb) and np.array_equal(lm.error, err) and np.array_equal(lm.hits, hits)
    assert lm.coverage is None
    photonlm.write_lightmap_exr(path, rgb)  # error and hits: zeros
    lm = photonlm.read_lightmap_exr(path)
    assert np.array_equal(lm.rgb, rgb) and not lm.error.any() and not lm.hits.any()


def test_reads_a_baked_lightmap_file(tmp_path):
    """A file the engine wrote for a baked mesh reads back as Result.lightmap holds it."""
    scene = photonlm.Scene()
    white = scene.add_material((0.5, 0.5, 0.5))
    pos, tri, uv = plane()
    mesh = scene.add_mesh("floor", pos, tri, uv, material_ids=np.full(len(tri), white, np.uint32), resolution=8)
    scene.add_light("POINT", color=(1, 1, 1), power=100.0, matrix=np.array(
        [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 1.0], [0, 0, 0, 1]], np.float64))
    with scene.bake(photons=20000, seed=1) as result:
        path = tmp_path / "floor.exr"
        result.write_exr(mesh, path)
        want = result.lightmap(mesh)
    got = photonlm.read_lightmap_exr(path)
    assert np.array_equal(got.rgb, want.rgb) and np.array_equal(got.error, want.error)
    assert np.array_equal(got.hits, want.hits) and want.rgb.max() > 0


def test_heat_map_round_trip(tmp_path):
    """A heat map: one value a texel, read back as the R, G and B of 16-bit floats."""
    values = np.linspace(0.001, 3.0, 35, dtype=np.float32).reshape(5, 7)
    path = tmp_path / "floor_error.exr"
    photonlm.write_heat_map_exr(path, values)
    got = photonlm.read_lightmap_exr(path)
    assert got.rgb.shape == (5, 7, 3)
    assert np.allclose(got.rgb[..., 0], values, rtol=5e-4)
    assert np.array_equal(got.rgb[..., 0], got.rgb[..., 1]) and np.array_equal(got.rgb[..., 0], got.rgb[..., 2])
    with pytest.raises(ValueError, match="values must have shape"):
        photonlm.write_heat_map_exr(path, np.zeros((4, 4, 3), np.float32))


def test_bad_input_is_refused(tmp_path):
    with pytest.raises(ValueError, match="rgb must have shape"):
        photonlm.write_lightmap_exr(tmp_path / "x.exr", np.zeros((4, 4), np.float32))
    with pytest.raises(ValueError, match="error must have shape"):
        photonlm.write_lightmap_exr(tmp_path / "x.exr", np.zeros((4, 4, 3), np.float32), np.zeros((4, 3)))
    with pytest.raises(photonlm.PhotonlmError, match="size 0 x 4"):
        photonlm.write_lightmap_exr(tmp_path / "x.exr", np.zeros((4, 0, 3), np.float32))
    with pytest.raises(photonlm.PhotonlmError, match="missing.exr"):
        photonlm.read_lightmap_exr(tmp_path / "missing.exr")
    (tmp_path / "text.exr").write_text("not an image")
    with pytest.raises(photonlm.PhotonlmError, match="text.exr"):
        photonlm.read_lightmap_exr(tmp_path / "text.exr")
