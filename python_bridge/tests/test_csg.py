"""CSG solids through the bridge: a numpy-built scene, checked against energy balance."""
import numpy as np
import pytest

import photonlm
from scenes import box_faces, QUAD_TRIANGLES, QUAD_UV


def scaled(s, at=(0.0, 0.0, 0.0)):
    m = np.eye(4)
    m[:3, :3] *= s
    m[:3, 3] = at
    return m


def test_black_shell_carrier_records_the_light_power():
    """A black shell (a box of half size 2 minus one of half size 1.5) around a 50 W point light:
    its carrier (the cavity's six inward faces, 3 x 3 m) records 50 W; the solid stands in for it.
    Tolerance 3 %: a carrier texel shows the solid's (half-size) texel at its point, like the
    default texel value (the texel's central half), not the texel average, and this field is
    peaked (measured +1.9 %); a plain mesh in the same place records half (it shares the
    surface with the solid)."""
    with photonlm.Scene() as scene:
        black = scene.add_material(albedo=0.0)
        shell = scene.add_csg("shell", [dict(shape="BOX", matrix=scaled(2.0), material=black),
                                        dict(shape="BOX", matrix=scaled(1.5), material=black)],
                              ("DIFFERENCE", 0, 1))
        faces = []
        for i, quad in enumerate(box_faces()):  # unit cube, inward: scale to [-1.5, 1.5]^3
            q = (np.asarray(quad, np.float32) - 0.5) * 3.0
            faces.append(q)
        pos = np.concatenate(faces)
        tris = np.concatenate([QUAD_TRIANGLES + 4 * i for i in range(6)])
        uv = np.concatenate([QUAD_UV * np.float32([1 / 3, 1 / 2]) + np.float32([(i % 3) / 3, (i // 3) / 2])
                             for i in range(6)])
        carrier = scene.add_mesh("cavity", pos, tris, uv, resolution=(24, 16))
        scene.set_csg_carrier(shell, carrier)
        scene.add_light("POINT", power=50.0, radius=0.0)
        with scene.bake(photons=300_000, direct_samples=0, seed=2) as result:
            lm = result.lightmap(carrier)
    texel_area = 9.0 / 64.0  # each 3 x 3 m face covers 8 x 8 texels
    flux = float((lm.rgb.mean(axis=2) * lm.coverage).sum() * np.pi * texel_area)
    assert flux == pytest.approx(50.0, rel=0.03)


def test_csg_errors_name_the_item():
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.5)
        with pytest.raises(ValueError, match="shape"):
            scene.add_csg("bad", [dict(shape="BLOB")], 0)
        with pytest.raises(photonlm.PhotonlmError, match="'loop'"):
            scene.add_csg("loop", [dict(shape="SPHERE", matrix=np.zeros((4, 4)))], 0)
        with pytest.raises(photonlm.PhotonlmError, match="material 5"):
            scene.add_csg("ball", [dict(shape="SPHERE", material=5)], 0)
