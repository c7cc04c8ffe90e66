"""The bridge fills the size that starts every caller-allocated struct (photonlm.h "Struct sizes"),
and the library refuses a struct whose size it does not know, naming it."""
import ctypes

import pytest

import photonlm
from photonlm import _lib
from scenes import plane, translation


def quad_scene(scene):
    scene.add_material(albedo=0.5)
    pos, tri, uv = plane(1.0)
    scene.add_mesh("floor", pos, tri, uv, resolution=8)
    scene.add_light("POINT", power=100.0, matrix=translation(0, 0, 1))


@pytest.mark.parametrize("name", _lib.SIZED_STRUCTS)
def test_every_struct_is_made_with_its_size(name):
    cls = getattr(_lib, name)
    assert cls._fields_[0] == ("struct_size", ctypes.c_uint32)
    assert cls().struct_size == ctypes.sizeof(cls)
    assert [item.struct_size for item in _lib.sized_array(cls, 3)] == [ctypes.sizeof(cls)] * 3


def test_defaults_keep_the_size():
    s = _lib.plm_bake_settings()
    _lib.lib.plm_bake_settings_default(ctypes.byref(s))
    assert s.struct_size == ctypes.sizeof(_lib.plm_bake_settings)


def test_stats_read_back_through_the_sized_struct():
    with photonlm.Scene() as scene:
        quad_scene(scene)
        with scene.bake(photons=20000, direct_samples=4) as result:
            stats = result.stats
            assert "struct_size" not in stats
            assert stats["photons_emitted"] >= 20000
            assert stats["memory_estimate"] > 0 and stats["seconds_total"] > 0
            raw = _lib.plm_bake_stats()
            assert _lib.lib.plm_result_stats(result._h, ctypes.byref(raw)) == 0
            assert raw.struct_size == ctypes.sizeof(raw)
            assert {k: getattr(raw, k) for k in stats} == stats


def test_wrong_size_is_refused_with_the_message():
    with photonlm.Scene() as scene:
        quad_scene(scene)
        with scene.bake(photons=5000, direct_samples=1) as result:
            raw = _lib.plm_bake_stats()
            raw.struct_size = 12
            with pytest.raises(photonlm.PhotonlmError) as e:
                photonlm._check(_lib.lib.plm_result_stats(result._h, ctypes.byref(raw)))
            assert e.value.status == "PLM_ERROR_STRUCT_SIZE"
            message = str(e.value)
            assert "plm_bake_stats" in message and "struct_size 12" in message
            assert "current %d" % ctypes.sizeof(raw) in message
            assert raw.photons_emitted == 0
        settings = _lib.plm_bake_settings()
        _lib.lib.plm_bake_settings_default(ctypes.byref(settings))
        settings.struct_size = ctypes.sizeof(settings) + 8
        out = _lib.ResultPtr()
        with pytest.raises(photonlm.PhotonlmError, match="plm_bake_settings.*struct_size %d" % (settings.struct_size)):
            photonlm._check(_lib.lib.plm_bake(scene._h, ctypes.byref(settings), _lib.progress_fn(0), None,
                                              ctypes.byref(out)))
