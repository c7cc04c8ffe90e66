"""Orientation-lightmap groups through the bridge, checked against the furnace's analytic answer."""
import math

import numpy as np
import pytest

import photonlm
from scenes import box_faces, QUAD_TRIANGLES, QUAD_UV


def oct_uv(d):
    """(u, v) of a unit direction in the equal-area octahedral map (Clarberg 2008)."""
    x, y, z = d
    r = math.sqrt((x * x + y * y) / (1.0 + abs(z)))
    b = math.atan2(abs(y), abs(x)) * 2.0 / math.pi * r
    a = r - b
    if z < 0:
        a, b = 1.0 - b, 1.0 - a
    return 0.5 * (math.copysign(a, x) + 1.0), 0.5 * (math.copysign(b, y) + 1.0)


def splatted_area(faces, n):
    """Each face's area over the n x n bins as the OL splats it: the bilinear weights of the four
    bin centres around its normal's (u, v), the square's edges glued as the octahedron folds."""
    def wrap(i, j):
        if i < 0:
            i, j = -i - 1, n - 1 - j
        elif i >= n:
            i, j = 2 * n - 1 - i, n - 1 - j
        if j < 0:
            i, j = n - 1 - i, -j - 1
        elif j >= n:
            i, j = n - 1 - i, 2 * n - 1 - j
        return j, i
    area = np.zeros((n, n))
    for quad in faces:
        c = np.cross(quad[1] - quad[0], quad[3] - quad[0]).astype(np.float64)
        u, v = oct_uv(c / np.linalg.norm(c))
        s, t = u * n - 0.5, v * n - 0.5
        i0, j0 = math.floor(s), math.floor(t)
        fx, fy = s - i0, t - j0
        for di, wx in ((0, 1.0 - fx), (1, fx)):
            for dj, wy in ((0, 1.0 - fy), (1, fy)):
                area[wrap(i0 + di, j0 + dj)] += np.linalg.norm(c) * wx * wy
    return area


def test_ol_furnace_box(tmp_path):
    """A closed box of 6 lightmap-less faces in one OL group: every face-normal bin reads E / (1 - rho)."""
    rho, emission = 0.5, 0.25
    truth = emission / (1.0 - rho)
    with photonlm.Scene() as scene:
        scene.add_material(albedo=rho, emission=emission)
        group = scene.add_ol_group("box", resolution=8)
        for i, quad in enumerate(box_faces()):
            scene.set_mesh_ol_group(scene.add_mesh("face%d" % i, quad, QUAD_TRIANGLES), group)
        with scene.bake(photons=400_000, seed=2) as result:
            ol = result.orientation_lightmap(group)
            stats = result.ol_stats(group)
            result.write_ol_exr(group, tmp_path / "box_ol.exr")
    assert ol.resolution == 8 and ol.rgb.shape == (8, 8, 3) and ol.error.shape == (8, 8)
    # Each unit face is splatted over 2 bins (+-x, +-y: on the square's edge) or 4 (+-z).
    expected = splatted_area(box_faces(), 8)
    assert np.allclose(ol.area, expected, rtol=0, atol=1e-6) and np.isclose(ol.area.sum(), 6.0)
    covered = ol.area > 0
    assert covered.sum() == (expected > 0).sum() == 16
    value = ol.rgb.mean(axis=2)
    assert np.all(value[~covered] == 0)
    z = (value[covered] - truth) / ol.error[covered]
    assert np.all(np.abs(z) < 4.5), (value[covered], ol.error[covered])
    assert abs(value[covered].mean() / truth - 1) < 0.01
    assert stats["mesh_count"] == 6 and stats["orphan_flux"] == 0
    assert stats["hits"] == ol.hits.sum()
    assert (tmp_path / "box_ol.exr").stat().st_size > 0


def test_ol_group_errors_name_the_culprit():
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.5)
        pos, tri = box_faces()[0], QUAD_TRIANGLES
        lit = scene.add_mesh("mapped", pos, tri, QUAD_UV, resolution=4)
        with pytest.raises(photonlm.PhotonlmError, match="1024"):
            scene.add_ol_group("big", resolution=4096)
        scene.add_ol_group("objects")
        with pytest.raises(photonlm.PhotonlmError, match="'mapped'.*OL group 9"):
            scene.set_mesh_ol_group(lit, 9)
        with pytest.raises(photonlm.PhotonlmError, match="mesh 7 does not exist"):
            scene.set_mesh_ol_group(7, 0)


def test_ol_and_lightmaps_in_one_furnace():
    """Half the faces lightmapped (direct pass + indirect photons), half in an OL group (all photon
    depths): both read E / (1 - rho), so neither double-counts nor misses the direct light."""
    rho, emission = 0.6, 1.0
    truth = emission / (1.0 - rho)
    with photonlm.Scene() as scene:
        scene.add_material(albedo=rho, emission=emission)
        group = scene.add_ol_group("half")
        mapped = []
        for i, quad in enumerate(box_faces()):
            if i % 2:
                mapped.append(scene.add_mesh("face%d" % i, quad, QUAD_TRIANGLES, QUAD_UV, resolution=6))
            else:
                scene.set_mesh_ol_group(scene.add_mesh("face%d" % i, quad, QUAD_TRIANGLES), group)
        with scene.bake(photons=1_000_000, seed=3, direct_samples=16) as result:
            ol = result.orientation_lightmap(group)
            lms = [result.lightmap(m) for m in mapped]
    assert ol.resolution == 16
    expected = splatted_area(box_faces()[0::2], 16)
    assert np.allclose(ol.area, expected, rtol=0, atol=1e-6)
    covered = ol.area > 0
    assert covered.sum() == (expected > 0).sum() == 8
    value = ol.rgb.mean(axis=2)[covered]
    assert np.all(np.abs(value - truth) < 4.5 * ol.error[covered]), (value, ol.error[covered])
    texels = np.concatenate([lm.rgb.mean(axis=2).ravel() for lm in lms])
    assert abs(texels.mean() / truth - 1) < 0.01, texels.mean()


def test_backup_ol_keeps_the_lightmap_and_its_truth():
    """A furnace box backed up by an OL: every texel still reads E / (1 - rho) within its error."""
    rho, emission = 0.5, 1.0
    truth = emission / (1.0 - rho)
    with photonlm.Scene() as scene:
        scene.add_material(albedo=rho, emission=emission)
        group = scene.add_ol_group("walls", resolution=8)
        scene.set_ol_group_backup(group)
        meshes = []
        for i, quad in enumerate(box_faces()):
            m = scene.add_mesh("face%d" % i, quad, QUAD_TRIANGLES, QUAD_UV, resolution=8)
            scene.set_mesh_ol_group(m, group)
            meshes.append(m)
        with scene.bake(photons=300_000, seed=2) as result:
            lms = [result.lightmap(m) for m in meshes]
            assert result.stats["direct_samples"] > 0
    values = np.concatenate([lm.rgb.mean(axis=2).ravel() for lm in lms])
    errors = np.concatenate([lm.error.ravel() for lm in lms])
    assert abs(values.mean() / truth - 1) < 0.01
    assert np.sqrt(np.mean(((values - truth) / errors) ** 2)) < 1.5
