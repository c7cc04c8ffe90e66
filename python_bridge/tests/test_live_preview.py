"""Live previews (Scene.bake(preview=...)): what they show against the furnace's analytic answer,
that they never change the result, and how they fail."""
import numpy as np
import pytest

import photonlm
from scenes import QUAD_TRIANGLES, QUAD_UV, box_faces, translation


def furnace(scene, rho=0.5, emission=1.0, res=8):
    """A closed box of emissive faces: every texel is exactly emission / (1 - rho), its direct
    part emission."""
    scene.add_material(albedo=rho, emission=emission)
    return [scene.add_mesh("face%d" % i, quad, QUAD_TRIANGLES, QUAD_UV, material_ids=[0, 0], resolution=res)
            for i, quad in enumerate(box_faces())]


def lit_box(scene, res=8):
    scene.add_material(albedo=0.8)
    meshes = [scene.add_mesh("face%d" % i, quad, QUAD_TRIANGLES, QUAD_UV, material_ids=[0, 0], resolution=res)
              for i, quad in enumerate(box_faces())]
    scene.add_light("POINT", power=50.0, matrix=translation(0.3, 0.4, 0.5))
    return meshes


def test_furnace_previews_show_direct_then_full_light():
    seen = []

    def preview(p):
        seen.append((p.photons, [p.lightmap(m) for m in meshes]))

    with photonlm.Scene() as scene:
        meshes = furnace(scene)
        with scene.bake(photons=600_000, seed=3, threads=2, direct_samples=16, preview=preview,
                        preview_interval=1e-6) as result:
            final = [result.lightmap(m) for m in meshes]
    assert len(seen) >= 3
    assert seen[0][0] == 0, "the first preview comes during the direct pass"
    photons = [n for n, _ in seen]
    lit = [n for n in photons if n > 0]
    assert photons == sorted(photons) and len(set(lit)) == len(lit) and lit
    for n, maps in seen:
        values = np.concatenate([rgb[f.coverage > 0].ravel() for rgb, f in zip(maps, final)])
        assert np.all(np.isfinite(values)) and values.min() >= 0.0
        if n == 0:
            assert values.mean() == pytest.approx(1.0, rel=0.02), "direct light alone"
        elif n >= 100_000:
            assert values.mean() == pytest.approx(2.0, rel=0.03), "preview at %d photons" % n


def test_previews_never_change_the_result(tmp_path):
    def bake(preview):
        with photonlm.Scene() as scene:
            meshes = lit_box(scene)
            with scene.bake(photons=200_000, seed=11, threads=2, direct_samples=8, preview=preview,
                            preview_interval=1e-6) as result:
                paths = []
                for m in meshes:
                    path = str(tmp_path / ("%s_%d.exr" % ("live" if preview else "plain", m)))
                    result.write_exr(m, path)
                    paths.append(path)
                return [result.lightmap(m) for m in meshes], paths, result.stats

    calls = []

    def preview(p):
        calls.append([p.lightmap(m) for m in range(6)])

    plain, plain_paths, plain_stats = bake(None)
    live, live_paths, live_stats = bake(preview)
    assert len(calls) >= 3
    for a, b in zip(plain, live):
        for x, y in zip(a, b):
            assert np.array_equal(x, y)
    for pa, pb in zip(plain_paths, live_paths):
        assert open(pa, "rb").read() == open(pb, "rb").read()
    assert plain_stats["error_estimate"] == live_stats["error_estimate"]
    assert plain_stats["photon_hits"] == live_stats["photon_hits"]


def test_preview_is_valid_only_during_the_call_and_can_fill_a_buffer():
    kept = []
    buffers = []

    def preview(p):
        out = np.full((8, 8, 3), -1.0, np.float32)
        assert p.lightmap(0, out=out) is out
        buffers.append(out)
        kept.append(p)
        with pytest.raises(ValueError):
            p.lightmap(0, out=np.empty((8, 8, 4), np.float32))
        with pytest.raises(photonlm.PhotonlmError, match="out of range"):
            p.lightmap(99)

    with photonlm.Scene() as scene:
        lit_box(scene)
        scene.bake(photons=50_000, threads=2, preview=preview, preview_interval=1e-6).close()
    assert buffers and all(b.min() >= 0.0 for b in buffers)
    with pytest.raises(photonlm.PhotonlmError, match="no longer valid"):
        kept[0].lightmap(0)


def test_preview_cancels_and_reraises():
    class Stop(Exception):
        pass

    def raising(p):
        raise Stop()

    with photonlm.Scene() as scene:
        lit_box(scene)
        with pytest.raises(Stop):
            scene.bake(photons=2_000_000, threads=2, preview=raising, preview_interval=1e-6)
        with pytest.raises(photonlm.BakeCancelled):
            scene.bake(photons=2_000_000, threads=2, preview=lambda p: False, preview_interval=1e-6)
        for bad in (-1.0, float("nan"), float("inf")):
            with pytest.raises(ValueError, match="preview_interval"):
                scene.bake(photons=1000, preview=lambda p: None, preview_interval=bad)
        scene.bake(photons=10_000, threads=2).close()  # the scene stays usable
