"""Specular lobes through the bridge: the sun through a clear glass slab onto a black floor bakes
to E (1 - R)^2 / pi in the direct pass (R = 0.04: exact Fresnel at IOR 1.5), a transparent veil
passes its colour, and bad lobes raise PhotonlmError naming the material and lobe."""
import numpy as np
import pytest

import photonlm

TRI = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
UV = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)


def quad(o, eu, ev):
    o, eu, ev = (np.asarray(v, np.float32) for v in (o, eu, ev))
    return np.array([o, o + eu, o + eu + ev, o + ev], np.float32)


def floor_under(kind, color, **lobe):
    with photonlm.Scene() as scene:
        black = scene.add_material(0.0, name="floor")
        cover = scene.add_material(0.0, name="cover")
        scene.add_material_lobe(cover, kind, color, **lobe)
        floor = scene.add_mesh("floor", quad((-0.5, -0.5, 0), (1, 0, 0), (0, 1, 0)), TRI, UV,
                               material_ids=[black, black], resolution=8)
        # The cover over the floor: one face (transparent) or a slab of two (glass).
        scene.add_mesh("top", quad((-1, -1, 1), (2, 0, 0), (0, 2, 0)), TRI, material_ids=[cover, cover])
        if kind == "glass":
            scene.add_mesh("bottom", quad((-1, -1, 0.99), (0, 2, 0), (2, 0, 0)), TRI, material_ids=[cover, cover])
        scene.add_light("SUN", power=2.0, angle=0.0)  # straight down
        with scene.bake(photons=1000, max_bounces=0, direct_samples=16) as result:
            return result.lightmap(floor).rgb.reshape(-1, 3)


def test_sun_through_a_glass_slab_is_the_fresnel_transmission_squared():
    rgb = floor_under("glass", 1.0, ior=1.5)
    np.testing.assert_allclose(rgb, 2.0 * 0.96 ** 2 / np.pi, rtol=1e-5)


def test_a_transparent_veil_passes_its_colour():
    rgb = floor_under("transparent", (0.2, 0.5, 0.8))
    np.testing.assert_allclose(rgb, np.tile(2.0 * np.array([0.2, 0.5, 0.8]) / np.pi, (64, 1)), rtol=1e-5)


def test_a_scene_file_keeps_the_lobes(tmp_path):
    from photonlm.scene_file import SceneFileWriter
    w = SceneFileWriter()
    m = w.add_material(0.1, name="gold")
    w.add_material_lobe(m, "fresnel", (1.0, 0.78, 0.34), roughness=0.2, weight=0.9)
    w.add_material_lobe(m, "refraction", 0.5, ior=1.33, abbe=55.0)
    doc = w.to_json()
    assert doc["materials"][0]["lobes"][0]["type"] == "fresnel"
    assert doc["materials"][0]["lobes"][1]["ior"] == pytest.approx(1.33)
    assert "ior" not in doc["materials"][0]["lobes"][0]  # None: the kind's default
    with pytest.raises(ValueError, match="lobe kind must be one of"):
        w.add_material_lobe(m, "mirror", 1.0)
    with pytest.raises(ValueError, match=r"material 0 lobe 2 \(glossy\): roughness 2.0 is not in \[0, 1\]"):
        w.add_material_lobe(m, "glossy", 0.1, roughness=2.0)
