"""Scene.bake_shard and Scene.merge: N shards baked through the bridge merge into what one Scene.bake
returns, bit for bit; parts that do not belong are refused naming the part."""
import os

import numpy as np
import pytest

import photonlm
from test_bake_control import box_scene

SETTINGS = dict(photons=120_000, direct_samples=4, seed=5)


def bake_parts(scene, n, folder, **extra):
    parts = []
    for k in range(n):
        parts.append(str(folder / ("part-%d-of-%d.plmpart" % (k, n))))
        scene.bake_shard(k, n, parts[-1], threads=1 + k % 2, **dict(SETTINGS, **extra))
    return parts


def same_bits(a, b, meshes):
    for m in meshes:
        x, y = a.lightmap(m), b.lightmap(m)
        for name in x._fields:
            assert np.array_equal(getattr(x, name).view(np.uint32), getattr(y, name).view(np.uint32)), (m, name)
    sa, sb = a.stats, b.stats
    for key in ("photons_emitted", "photon_hits", "rays_traced", "error_estimate", "error_p95"):
        assert sa[key] == sb[key], key


def test_merge_equals_one_bake_for_any_shard_count(tmp_path):
    with photonlm.Scene() as scene:
        meshes = box_scene(scene, rho=0.7)
        with scene.bake(**SETTINGS) as one:
            for n in (1, 2, 3):
                folder = tmp_path / str(n)
                folder.mkdir()
                parts = bake_parts(scene, n, folder, scene_path="box.json")
                info = photonlm.part_info(parts[-1])
                assert info["shard"] == n - 1 and info["shard_count"] == n and info["scene_path"] == "box.json"
                assert info["settings"]["photons"] == SETTINGS["photons"]
                assert info["settings"]["seed"] == SETTINGS["seed"]
                assert info["settings"]["texel_value"] == "CYCLES"
                with scene.merge(reversed(parts), threads=2) as merged:  # any order
                    same_bits(one, merged, meshes)
        # The merge is the bake, not a copy of itself: another seed gives other bits.
        with scene.bake(**dict(SETTINGS, seed=6)) as other, scene.merge(parts) as merged:
            assert not np.array_equal(other.lightmap(meshes[0]).rgb, merged.lightmap(meshes[0]).rgb)


def test_merge_refuses_parts_that_do_not_belong(tmp_path):
    with photonlm.Scene() as scene:
        box_scene(scene)
        parts = bake_parts(scene, 3, tmp_path)
        other_seed = str(tmp_path / "seed.plmpart")
        scene.bake_shard(1, 3, other_seed, **dict(SETTINGS, seed=9))
        cases = {
            "missing": (parts[:2], "shard"),
            "repeated": (parts + [parts[0]], os.path.basename(parts[0])),
            "other seed": ([parts[0], other_seed, parts[2]], "seed.plmpart"),
            "no such file": (parts[:2] + [str(tmp_path / "absent.plmpart")], "absent.plmpart"),
        }
        for what, (given, named) in cases.items():
            with pytest.raises(photonlm.PhotonlmError) as e:
                scene.merge(given)
            assert named in str(e.value), (what, str(e.value))
        truncated = tmp_path / "cut.plmpart"
        truncated.write_bytes(open(parts[2], "rb").read()[:1000])
        with pytest.raises(photonlm.PhotonlmError) as e:
            scene.merge(parts[:2] + [str(truncated)])
        assert "cut.plmpart" in str(e.value)
        with pytest.raises(photonlm.PhotonlmError) as e:
            photonlm.part_info(str(truncated))
        assert "cut.plmpart" in str(e.value)


def test_shard_refuses_what_cannot_be_split(tmp_path):
    with photonlm.Scene() as scene:
        box_scene(scene)
        part = str(tmp_path / "p.plmpart")
        for bad, named in ((dict(target_error=0.02), "target"), (dict(time_budget=5.0), "time budget"),
                           (dict(photons=0), "photon_count")):
            with pytest.raises(photonlm.PhotonlmError) as e:
                scene.bake_shard(0, 2, part, **dict(SETTINGS, **bad))
            assert named in str(e.value), str(e.value)
        for k, n in ((2, 2), (0, 0)):
            with pytest.raises(photonlm.PhotonlmError):
                scene.bake_shard(k, n, part, **SETTINGS)
        with pytest.raises(TypeError):
            scene.bake_shard(0, 2, part, photon=1000)  # a misspelt setting is not ignored
        assert not os.path.exists(part)


def test_progress_and_cancel_of_a_shard(tmp_path):
    with photonlm.Scene() as scene:
        box_scene(scene)
        seen = []
        part = str(tmp_path / "p.plmpart")
        scene.bake_shard(0, 2, part, progress=lambda f, s: seen.append(f), **SETTINGS)
        assert seen and seen[-1] == pytest.approx(1.0) and os.path.getsize(part) > 0
        with pytest.raises(photonlm.BakeCancelled):
            scene.bake_shard(1, 2, str(tmp_path / "q.plmpart"), progress=lambda f, s: False, **SETTINGS)
        assert not os.path.exists(tmp_path / "q.plmpart")  # nothing half-written
