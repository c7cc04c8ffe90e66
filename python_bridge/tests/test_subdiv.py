"""Subdivision surfaces (Scene.add_subdiv_mesh): a Catmull-Clark cube cage refined by the engine."""
import numpy as np
import pytest

import photonlm

CUBE = np.array([[1, 1, 1], [1, 1, -1], [1, -1, 1], [1, -1, -1],
                 [-1, 1, 1], [-1, 1, -1], [-1, -1, 1], [-1, -1, -1]], np.float32)
FACES = np.array([[0, 4, 6, 2], [3, 2, 6, 7], [7, 6, 4, 5], [5, 1, 3, 7], [1, 0, 2, 3], [5, 4, 0, 1]])


def cube_uv():
    """Each face its own island in a 3 x 2 layout with margins (corner order of FACES)."""
    uv = []
    for f in range(6):
        u0, v0 = (f % 3) / 3 + 0.02, (f // 3) / 2 + 0.02
        s, t = 1 / 3 - 0.04, 1 / 2 - 0.04
        uv += [(u0, v0), (u0 + s, v0), (u0 + s, v0 + t), (u0, v0 + t)]
    return np.array(uv, np.float32)


def test_convex_subdivided_cube_under_uniform_sky_sees_the_sky():
    """The limit surface of a cube is convex: under world radiance L every point's irradiance / pi is L,
    whatever the albedo (no surface sees another)."""
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.6)
        scene.set_world((1.0, 1.0, 1.0))
        mesh = scene.add_subdiv_mesh("cube", CUBE, np.full(6, 4), FACES.ravel(), level=3,
                                     lightmap_uv=cube_uv(), resolution=48)
        with scene.bake(photons=400_000, seed=4) as result:
            lm = result.lightmap(mesh)
    inside = lm.coverage > 0.99
    assert inside.sum() > 0.6 * 48 * 48 * (1 - 0.12 * 6)  # the six islands are covered
    values = lm.rgb.mean(axis=2)[inside]
    assert values.mean() == pytest.approx(1.0, abs=0.01)
    z = (values - 1.0) / lm.error[inside]
    assert np.abs(z).max() < 6, np.abs(z).max()


def test_subdiv_mesh_errors_name_mesh_and_index():
    with photonlm.Scene() as scene:
        with pytest.raises(photonlm.PhotonlmError, match="mesh 'c': crease 0 names the edge 0-7"):
            scene.add_subdiv_mesh("c", CUBE, np.full(6, 4), FACES.ravel(), level=2,
                                  crease_edges=[[0, 7]], crease_weights=[1.0])
        bad = FACES.copy()
        bad[3, 2] = 9
        with pytest.raises(photonlm.PhotonlmError, match="cage face 3 corner 2 uses vertex 9"):
            scene.add_subdiv_mesh("c", CUBE, np.full(6, 4), bad.ravel(), level=2)
        with pytest.raises(photonlm.PhotonlmError, match="level 0"):
            scene.add_subdiv_mesh("c", CUBE, np.full(6, 4), FACES.ravel(), level=0)
        with pytest.raises(ValueError, match="sum\\(face_sizes\\)"):
            scene.add_subdiv_mesh("c", CUBE, np.full(6, 4), FACES.ravel()[:-1], level=2)
        with pytest.raises(ValueError, match="lightmap_uv"):
            scene.add_subdiv_mesh("c", CUBE, np.full(6, 4), FACES.ravel(), level=2,
                                  lightmap_uv=np.zeros((23, 2)), resolution=8)
        # A good one still works after the errors, with creases.
        mid = scene.add_subdiv_mesh("c", CUBE, np.full(6, 4), FACES.ravel(), level=2,
                                    crease_edges=[[0, 4], [4, 6]], crease_weights=[1.0, 0.5])
        assert mid == 0


def test_subdiv_refine_returns_the_limit_surface():
    """Cube corners go to (+-1/2)^3 and face centres to 68/81 (Catmull-Clark limit masks)."""
    for level in (1, 2, 3):
        pos, tris, uv = photonlm.subdiv_refine(CUBE, np.full(6, 4), FACES.ravel(), level, lightmap_uv=cube_uv())
        assert tris.shape == (48 * 4 ** (level - 1), 3) and uv.shape == (tris.shape[0], 3, 2)
        assert tris.max() == pos.shape[0] - 1
        assert np.sum(np.all(np.abs(np.abs(pos) - 0.5) < 1e-6, axis=1)) == 8
        assert np.abs(pos).max() == pytest.approx(68 / 81, abs=1e-6)
        # PRESERVE_BOUNDARIES: every face's UVs stay inside its island.
        assert uv.min() >= 0.02 - 1e-6 and uv.max() <= 1 - 0.02 + 1e-6
    pos, tris, uv = photonlm.subdiv_refine(CUBE, np.full(6, 4), FACES.ravel(), 2)
    assert uv is None


def test_ol_group_limit_area_uses_the_limit_surface():
    """A level-1 cube cage (+-1) in an OL group: by default its bins hold the refined triangles'
    area (8.125 m^2); with limit_area the limit surface's larger area (9.197 m^2, which the C++
    tests check against level-7 triangles)."""
    areas = []
    for limit in (False, True):
        with photonlm.Scene() as scene:
            scene.add_material(albedo=0.5)
            scene.set_world((1.0, 1.0, 1.0))
            mesh = scene.add_subdiv_mesh("cube", CUBE, np.full(6, 4), FACES.ravel(), level=1)
            group = scene.add_ol_group("blob", resolution=8)
            scene.set_mesh_ol_group(mesh, group)
            scene.set_ol_group_limit_area(group, limit)
            with scene.bake(photons=20_000, seed=1) as result:
                areas.append(result.ol_stats(group)["area"])
    assert areas[0] == pytest.approx(8.12497, rel=1e-4)
    assert areas[1] == pytest.approx(9.1973, rel=2e-3)
    with photonlm.Scene() as scene:
        with pytest.raises(photonlm.PhotonlmError, match="OL group 3 does not exist"):
            scene.set_ol_group_limit_area(3)
