"""The bridge's contract: types match the C header, bad input is refused with useful messages."""
import ctypes
import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

import photonlm
from photonlm import _lib
from scenes import clip_area, plane, translation

HEADER = os.path.join(os.path.dirname(__file__), "..", "..", "native", "include", "photonlm", "photonlm.h")


def header_text():
    with open(HEADER) as f:
        return f.read()


def test_version_matches_header():
    parts = [re.search(r"#define PLM_VERSION_%s (\d+)" % k, header_text()).group(1)
             for k in ("MAJOR", "MINOR", "PATCH")]
    assert photonlm.version() == ".".join(parts)


@pytest.mark.skipif(shutil.which("cc") is None, reason="needs a C compiler")
def test_struct_layouts_match_header(tmp_path):
    """Compile the header and compare sizeof/offsetof of every struct with the ctypes declarations."""
    structs = {name: getattr(_lib, name) for name in _lib.SIZED_STRUCTS}
    lines = []
    for name, cls in structs.items():
        lines.append('printf("%s size %%zu\\n", sizeof(%s));' % (name, name))
        for field, _ in cls._fields_:
            lines.append('printf("%s %s %%zu\\n", offsetof(%s, %s));' % (name, field, name, field))
    src = tmp_path / "layout.c"
    src.write_text('#include <stdio.h>\n#include <stddef.h>\n#include "photonlm/photonlm.h"\n'
                   "int main(void) {\n%s\nreturn 0;\n}\n" % "\n".join(lines))
    exe = tmp_path / "layout"
    subprocess.run(["cc", "-std=c99", "-I", os.path.dirname(os.path.dirname(HEADER)), str(src), "-o", str(exe)],
                   check=True)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split("\n")
    for line in filter(None, out):
        name, field, value = line.split()
        cls = structs[name]
        got = ctypes.sizeof(cls) if field == "size" else getattr(cls, field).offset
        assert got == int(value), "%s.%s: ctypes %d, C %s" % (name, field, got, value)
    # Field sets equal too (a field missing in ctypes would not show up above).
    for name, cls in structs.items():
        body = re.search(r"typedef struct %s \{(.*?)\} %s;" % (name, name), header_text(), re.S).group(1)
        c_fields = re.findall(r"(\w+)(?:\[\d+\])?\s*[;,]", re.sub(r"/\*.*?\*/", "", body, flags=re.S))
        assert [f for f, _ in cls._fields_] == c_fields


def test_handle_types_are_distinct():
    with photonlm.Scene() as scene:
        with pytest.raises(ctypes.ArgumentError):
            _lib.lib.plm_result_warning_count(scene._handle)


def test_missing_library_names_both_places(tmp_path):
    here = os.path.dirname(photonlm.__file__)
    if any(f.startswith("libphotonlm") for f in os.listdir(here)):
        pytest.skip("a library sits next to the package")
    env = dict(os.environ, PHOTONLM_LIBRARY=str(tmp_path / "nowhere.so"))
    r = subprocess.run([sys.executable, "-c", "import photonlm"], env=env, capture_output=True, text=True)
    assert r.returncode != 0
    assert "LibraryNotFoundError" in r.stderr and "nowhere.so" in r.stderr
    assert os.path.join(here, "libphotonlm.so") in r.stderr


def simple_scene(scene):
    scene.add_material(albedo=0.5)
    pos, tri, uv = plane(1.0)
    mesh = scene.add_mesh("floor", pos, tri, uv, resolution=8)
    scene.add_light("POINT", power=100.0, matrix=translation(0, 0, 1))
    return mesh


def test_nan_position_names_mesh_and_vertex():
    pos = np.zeros((9, 3), np.float32)
    pos[:, 0] = np.arange(9)
    pos[:, 1] = np.arange(9) % 2
    pos[6, 2] = np.nan
    tri = np.array([[0, 1, 2], [2, 3, 4], [4, 5, 6], [6, 7, 8]], np.int64)
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.5)
        with pytest.raises(photonlm.PhotonlmError) as e:
            scene.add_mesh("wonky_mesh", pos, tri)
    assert e.value.status == "PLM_ERROR_INVALID_ARGUMENT"
    assert "wonky_mesh" in e.value.message and re.search(r"\b6\b", e.value.message), e.value.message


def test_triangle_index_out_of_range_names_mesh_and_triangle():
    pos = np.random.default_rng(0).random((12, 3)).astype(np.float32)
    tri = np.arange(30).reshape(10, 3) % 12
    tri[7, 1] = 40
    with photonlm.Scene() as scene:
        with pytest.raises(photonlm.PhotonlmError) as e:
            scene.add_mesh("ranged", pos, tri)
    assert e.value.status == "PLM_ERROR_INVALID_ARGUMENT"
    assert "ranged" in e.value.message and re.search(r"\b7\b", e.value.message), e.value.message


def test_missing_uvs_with_resolution():
    pos, tri, _ = plane()
    with photonlm.Scene() as scene:
        with pytest.raises(photonlm.PhotonlmError) as e:
            scene.add_mesh("uvless", pos, tri, resolution=16)
        assert "uvless" in e.value.message, e.value.message
        assert e.value.status == "PLM_ERROR_INVALID_ARGUMENT"
        scene.add_mesh("uvless_geometry", pos, tri)  # fine without a lightmap


@pytest.mark.parametrize("change, argument", [
    (dict(positions=np.zeros((4, 2))), "positions"),
    (dict(triangles=np.zeros((2, 4), int)), "triangles"),
    (dict(triangles=[[0, 1, -2], [0, 2, 3]]), "triangles"),
    (dict(triangles=np.zeros((2, 3), np.float32)), "triangles"),
    (dict(lightmap_uv=np.zeros((2, 2, 2))), "lightmap_uv"),
    (dict(lightmap_uv=np.zeros((5, 2))), "lightmap_uv"),
    (dict(material_ids=[0, 0, 0]), "material_ids"),
    (dict(material_ids=[0, -1]), "material_ids"),
    (dict(resolution=-4), "resolution"),
    (dict(resolution=(4, 4, 4)), "resolution"),
])
def test_wrong_shapes_raise_value_error(change, argument):
    pos, tri, uv = plane()
    kw = dict(positions=pos, triangles=tri, lightmap_uv=uv, resolution=4)
    kw.update(change)
    with photonlm.Scene() as scene:
        with pytest.raises(ValueError, match=argument):
            scene.add_mesh("m", **kw)


def test_uv_layouts_and_int_dtypes_accepted():
    pos, tri, uv = plane()
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.5)
        assert scene.add_mesh("a", pos.astype(np.float64), tri.astype(np.int16), uv.reshape(6, 2), resolution=(4, 2)) == 0
        assert scene.add_mesh("b", pos.tolist(), tri.tolist(), uv.tolist(), material_ids=[0, 0], resolution=4) == 1


@pytest.mark.parametrize("kind, fields, field", [
    ("SPOT", dict(spot_size=-0.5), "spot_size"),
    ("SPOT", dict(spot_blend=1.5), "spot_blend"),
    ("AREA_RECT", dict(size=0.0), "size"),
    ("AREA_DISK", dict(size=1.0, size_y=0.0), "size"),
    ("AREA_RECT", dict(matrix=np.diag([1.0, 0.0, 1.0, 1.0])), "area"),
    ("POINT", dict(power=float("nan")), "power"),
    ("POINT", dict(color=(1.0, -1.0, 0.0)), "color"),
    ("SUN", dict(angle=-0.1), "angle"),
])
def test_bad_lights_are_refused(kind, fields, field):
    with photonlm.Scene() as scene:
        with pytest.raises(photonlm.PhotonlmError) as e:
            scene.add_light(kind, name="lamp_x", **fields)
    assert e.value.status == "PLM_ERROR_INVALID_ARGUMENT"
    assert "lamp_x" in e.value.message and field in e.value.message, e.value.message


def test_material_id_out_of_range_names_mesh_and_triangle():
    pos, tri, uv = plane()
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.5)
        with pytest.raises(photonlm.PhotonlmError) as e:
            scene.add_mesh("painted", pos, tri, uv, material_ids=[0, 3], resolution=4)
    assert "painted" in e.value.message and re.search(r"triangle 1\b", e.value.message), e.value.message


def test_light_type_and_matrix_checked_in_python():
    with photonlm.Scene() as scene:
        with pytest.raises(ValueError, match="POINT"):
            scene.add_light("LASER")
        with pytest.raises(ValueError, match="4x4"):
            scene.add_light("SUN", matrix=np.eye(3))
        assert scene.add_light("sun", matrix=np.eye(4).tolist()) == 0


def test_bad_materials_are_refused():
    with photonlm.Scene() as scene:
        with pytest.raises(photonlm.PhotonlmError):
            scene.add_material(albedo=(1.2, 0.5, 0.5))
        with pytest.raises(photonlm.PhotonlmError):
            scene.add_material(albedo=0.5, emission=(float("inf"), 0, 0))
        with pytest.raises(ValueError, match="albedo"):
            scene.add_material(albedo=(0.5, 0.5))
        with pytest.raises(photonlm.PhotonlmError):
            scene.set_world((0.1, float("nan"), 0.1))
        assert scene.add_material(albedo=0.5, name="ok") == 0


def test_material_lobes_are_checked_and_named():
    with photonlm.Scene() as scene:
        glass = scene.add_material(albedo=0.0, name="glass")
        scene.add_material_lobe(glass, "glass", (0.9, 1.0, 0.9))  # ior None: the kind's default
        scene.add_material_lobe(glass, "fresnel", 0.04, roughness=0.1, weight=0.25)
        with pytest.raises(ValueError, match="lobe kind must be one of"):
            scene.add_material_lobe(glass, "chrome", 1.0)
        with pytest.raises(ValueError, match="lobe color"):
            scene.add_material_lobe(glass, "glossy", (1.0, 1.0))
        with pytest.raises(photonlm.PhotonlmError, match=r"material 'glass': lobe 2 \(glass\): ior 0 must be > 0"):
            scene.add_material_lobe(glass, "glass", 0.5, ior=0.0)
        with pytest.raises(photonlm.PhotonlmError, match=r"lobe 2 \(refraction\): color\[0\] = nan"):
            scene.add_material_lobe(glass, "refraction", (float("nan"), 0, 0))
        with pytest.raises(photonlm.PhotonlmError, match="abbe 40 is for glass and refraction lobes only"):
            scene.add_material_lobe(glass, "glossy", 0.0, abbe=40.0)
        with pytest.raises(photonlm.PhotonlmError, match="above 1"):
            scene.add_material_lobe(glass, "transparent", 0.5)  # glass (1) + 0.5 > 1
        with pytest.raises(photonlm.PhotonlmError, match="out of range"):
            scene.add_material_lobe(5, "glossy", 0.5)


def test_empty_scene_cannot_be_baked():
    with photonlm.Scene() as scene:
        with pytest.raises(photonlm.PhotonlmError) as e:
            scene.bake(photons=1000)
    assert type(e.value) is photonlm.PhotonlmError and e.value.message
    assert e.value.status in ("PLM_ERROR_INVALID_SCENE", "PLM_ERROR_INVALID_ARGUMENT")


def test_scene_without_any_light():
    """No lights, emission or world: the engine refuses the bake and says why."""
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.5)
        pos, tri, uv = plane()
        scene.add_mesh("dark", pos, tri, uv, resolution=4)
        with pytest.raises(photonlm.PhotonlmError) as e:
            scene.bake(photons=1000)
        assert e.value.status == "PLM_ERROR_INVALID_SCENE"
        assert "nothing lights the scene" in e.value.message


def test_result_arrays_and_coverage():
    """Shapes, dtypes, row order, exact texel coverage of a UV triangle, and geometry-only meshes."""
    width, height = 8, 4
    uv_tri = np.array([[0.05, 0.1], [0.9, 0.3], [0.4, 0.95]])
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.0)
        mesh = scene.add_mesh("tri", pos, [[0, 1, 2]], uv_tri[None], resolution=(width, height))
        geo = scene.add_mesh("geo", pos + np.float32([0, 0, -1]), [[0, 1, 2]])
        scene.add_light("SUN", power=1.0)
        with scene.bake(photons=20_000, dilation=0, direct_samples=0) as result:  # photons only: every covered texel records hits
            assert result.lightmap_size(mesh) == (width, height)
            lm = result.lightmap(mesh)
            # A geometry-only mesh has no lightmap: the engine refuses to report one.
            with pytest.raises(photonlm.PhotonlmError, match="no lightmap"):
                result.lightmap_size(geo)
            with pytest.raises(photonlm.PhotonlmError, match="7"):
                result.lightmap_size(7)
    assert isinstance(lm, photonlm.Lightmap)
    assert lm.rgb.shape == (height, width, 3) and lm.rgb.dtype == np.float32
    for a in (lm.error, lm.hits, lm.coverage):
        assert a.shape == (height, width) and a.dtype == np.float32
    truth = np.array([[clip_area(uv_tri, i / width, (i + 1) / width, j / height, (j + 1) / height) * width * height
                       for i in range(width)] for j in range(height)])
    assert np.abs(lm.coverage - truth).max() < 1e-3, np.round(lm.coverage - truth, 3)
    # Uncovered texels get no photons when not dilated.
    assert np.all(lm.hits[truth == 0] == 0) and np.all(lm.hits[truth > 0.2] > 0)


def test_closed_handles():
    scene = photonlm.Scene()
    mesh = simple_scene(scene)
    result = scene.bake(photons=1000)
    scene.close()
    scene.close()
    with pytest.raises(ValueError, match="closed"):
        scene.add_material(albedo=0.1)
    assert result.lightmap(mesh).rgb.shape == (8, 8, 3)  # a result outlives its scene
    result.close()
    with pytest.raises(ValueError, match="closed"):
        result.stats


def test_stats_keys():
    with photonlm.Scene() as scene:
        simple_scene(scene)
        with scene.bake(photons=5000) as result:
            stats = result.stats
    assert set(stats) == {"photons_emitted", "photon_hits", "rays_traced", "paths_truncated", "emitted_power",
                          "seconds_setup", "seconds_trace", "seconds_total", "direct_samples", "seconds_direct",
                          "error_estimate", "error_direct", "error_median", "error_p95", "error_above",
                          "memory_estimate", "error_worst", "error_worst_mesh"}
    assert stats["photons_emitted"] == 5000
    assert 0 <= stats["error_above"] <= 1 and stats["memory_estimate"] > 0
    # One object: the noisiest is it, its error the whole's.
    assert stats["error_worst_mesh"] == 0
    assert stats["error_worst"] == pytest.approx(stats["error_estimate"], rel=1e-9)
    assert stats["rays_traced"] >= stats["photons_emitted"]
    assert 0 <= stats["seconds_setup"] <= stats["seconds_total"] and 0 <= stats["seconds_trace"] <= stats["seconds_total"]


def test_defaults_come_from_the_engine():
    """Scene.bake's settings left None are the engine's (plm_bake_settings_default), and
    default_settings() names exactly Scene.bake's settings."""
    import inspect
    d = photonlm.default_settings()
    params = set(inspect.signature(photonlm.Scene.bake).parameters) - {"self", "progress", "preview", "preview_interval"}
    assert set(d) == params
    assert d["photons"] > 0 and d["max_bounces"] > 0 and d["texel_value"] in ("CYCLES", "AREA")
    with photonlm.Scene() as scene:
        simple_scene(scene)
        with scene.bake(direct_samples=4) as result:  # everything else from the engine
            assert result.stats["photons_emitted"] == d["photons"]
