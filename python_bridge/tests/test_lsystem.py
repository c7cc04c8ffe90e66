"""L-system objects through the bridge: flatten a plant, bake it over a floor, read its light back."""
import numpy as np
import pytest

import photonlm
from scenes import plane

PLANT = """
angle: 30
step: 0.3
width: 0.08
depth: 3
axiom: A
A -> F [+A] [-A]
"""


def test_lsystem_flatten_bake_lookup_and_shadow():
    shapes, matrices, materials, truncated = photonlm.lsystem_flatten(PLANT, matrix=np.eye(4))
    assert shapes.shape == (7,) and matrices.shape == (7, 3, 4) and materials.shape == (7,)
    assert not truncated
    assert all(photonlm.LSYSTEM_SHAPES[int(s)] == "CYLINDER" for s in shapes)
    assert np.isclose(matrices[0, 2, 3], 0.15)  # the trunk: centred half a step above the origin
    few = photonlm.lsystem_flatten(PLANT, max_primitives=2)
    assert few[0].shape == (2,) and few[3]

    lift = np.eye(4)
    lift[2, 3] = 0.5
    with photonlm.Scene() as scene:
        white = scene.add_material(albedo=0.8)
        green = scene.add_material(albedo=(0.1, 0.5, 0.1))
        pos, tri, uv = plane(half=2.0)
        floor = scene.add_mesh("floor", pos, tri, lightmap_uv=uv, resolution=32)
        scene.add_light("SUN", power=2.0, angle=0.0)
        plant = scene.add_lsystem("plant", PLANT, matrix=lift, width=0.3, materials=[green], ol_level=2)
        with pytest.raises(photonlm.PhotonlmError, match="line 2, column"):
            scene.add_lsystem("bad", "axiom: F\nA -> F(\n")
        with scene.bake(photons=300_000, direct_samples=16, seed=1) as result:
            lm = result.lightmap(floor)
            stats = result.lsystem_stats(plant)
            # The top of the trunk (z = 0.5 + 0.3 under the branches) and the side of the trunk.
            points = np.array([[0.15, 0.0, 0.65], [-0.15, 0.0, 0.65], [0.0, 0.0, 0.5]], np.float32)
            normals = np.array([[1, 0, 0], [-1, 0, 0], [0, 0, -1]], np.float32)
            rgb = result.lsystem_lookup(plant, points, normals)
    assert stats["primitives"] == 7 and stats["hits"] > 0 and stats["stub_instances"] == 3
    assert stats["area"] > 0 and stats["flux"] > 0
    assert rgb.shape == (3, 3) and np.all(np.isfinite(rgb)) and np.all(rgb >= 0)
    assert rgb[:, 1].max() > 0  # the floor's bounce light reaches the trunk
    # The shadow: the trunk (width 0.3) stands over the floor's centre (texels 15, 16), the sun above.
    value = lm.rgb.mean(axis=2)
    under = value[15:17, 15:17].mean()
    open_floor = np.median(value)
    assert under < 0.5 * open_floor, (under, open_floor)
    assert abs(open_floor - 2.0 / np.pi) < 0.05 * 2.0 / np.pi
