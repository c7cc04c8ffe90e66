"""Bakes checked against analytic answers. Values are irradiance / pi (see photonlm.h)."""
import math

import numpy as np
import pytest

import photonlm
from scenes import box_faces, plane, rotation_x, texel_average, translation, QUAD_TRIANGLES, QUAD_UV


def check_against_truth(lm, truth, what, max_z=6.0):
    """Texels agree with truth within their reported standard errors, and those errors are honest."""
    check_values(lm.rgb.mean(axis=2), lm.error, truth, what, max_z)


def check_values(mean_rgb, error, truth, what, max_z=6.0):
    assert np.all(error > 0), "%s: texels without an error estimate: %d" % (what, np.sum(error <= 0))
    z = (mean_rgb - truth) / error
    rms_z = float(np.sqrt(np.mean(z ** 2)))
    worst = np.unravel_index(np.argmax(np.abs(z)), z.shape)
    assert np.abs(z).max() < max_z, "%s: texel %s = %g, truth %g, error %g (z = %.1f)" % (
        what, worst, mean_rgb[worst], truth[worst] if np.ndim(truth) else truth, error[worst], z[worst])
    # The spread around truth must match the reported error (neither hidden noise nor inflated bars).
    assert 1 / 1.5 < rms_z < 1.5, "%s: rms of (value - truth) / error is %.2f, expected ~1" % (what, rms_z)


@pytest.mark.parametrize("rho", [0.5, 0.9])
def test_furnace_closed_box(rho):
    """Uniform emission E and albedo rho inside a closed box: incident radiance E / (1 - rho) everywhere."""
    emission = 0.25
    truth = emission / (1.0 - rho)
    with photonlm.Scene() as scene:
        scene.add_material(albedo=rho, emission=emission)
        meshes = [scene.add_mesh("face%d" % i, quad, QUAD_TRIANGLES, QUAD_UV, resolution=12)
                  for i, quad in enumerate(box_faces())]
        with scene.bake(photons=4_000_000 if rho < 0.7 else 2_000_000, seed=1) as result:
            lms = [result.lightmap(m) for m in meshes]
            stats = result.stats
    values = np.concatenate([lm.rgb.reshape(-1, 3) for lm in lms])
    assert np.allclose(np.concatenate([lm.coverage.ravel() for lm in lms]), 1.0, atol=1e-4)
    # Every channel is the same (white), the mean is within 1% of truth.
    for c in range(3):
        assert abs(values[:, c].mean() / truth - 1) < 0.01, (c, values[:, c].mean(), truth)
    # The six faces as one: one face's 144 texels (correlated by the filter)
    # give a noisy RMS z (0.63-1.07 over the faces at rho 0.9).
    check_values(np.concatenate([lm.rgb.mean(axis=2).ravel() for lm in lms]),
                 np.concatenate([lm.error.ravel() for lm in lms]), truth, "furnace rho=%g" % rho)
    # Emitted power: 6 unit faces, both sides emit (the outer sides into the void): 2 pi E A.
    assert stats["emitted_power"] == pytest.approx(2 * math.pi * emission * 6, rel=1e-3)
    assert stats["photons_emitted"] > 0 and stats["photon_hits"] > 0


def test_point_light_over_plane():
    """Irradiance from a point light of power P at height h: P / (4 pi) * h / d^3; the lightmap holds E / pi."""
    power, h, lx, ly, res = 1000.0, 1.0, -0.6, 0.8, 32
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.0)
        pos, tri, uv = plane(2.0)
        mesh = scene.add_mesh("floor", pos, tri, uv, resolution=res)
        scene.add_light("POINT", power=power, radius=0.0, matrix=translation(lx, ly, h))
        # Photons only (direct_samples=0): tests the photon estimator and its error channel.
        with scene.bake(photons=15_000_000, max_bounces=0, seed=3, direct_samples=0) as result:
            lm = result.lightmap(mesh)
            stats = result.stats

    def value(x, y):
        d2 = (x - lx) ** 2 + (y - ly) ** 2 + h * h
        return power / (4 * math.pi) * h / d2 ** 1.5 / math.pi

    truth = texel_average(value, -2, 2, -2, 2, res, res)
    check_against_truth(lm, truth, "point light")
    assert np.allclose(lm.rgb[..., 0], lm.rgb[..., 1]) and np.allclose(lm.rgb[..., 0], lm.rgb[..., 2])
    # Total flux on the plane (sum of E * texel area) within 1%.
    assert lm.rgb.mean(axis=2).sum() / truth.sum() == pytest.approx(1.0, abs=0.01)
    # Row 0 is v = 0 (y = -2): the brightest 3x3 neighbourhood sits under the light at (u, v) = (0.35, 0.7).
    m = lm.rgb.mean(axis=2)
    box = sum(np.roll(np.roll(m, dy, 0), dx, 1) for dy in (-1, 0, 1) for dx in (-1, 0, 1))
    row, col = np.unravel_index(np.argmax(box), box.shape)
    assert abs(row - 0.7 * res + 0.5) <= 2 and abs(col - 0.35 * res + 0.5) <= 2, (row, col)
    assert stats["emitted_power"] == pytest.approx(power, rel=1e-3)


def test_sun_over_plane():
    """A sun of strength S at angle theta from the normal gives E = S cos(theta) on every texel."""
    strength, theta = 3.0, math.radians(30)
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.0)
        pos, tri, uv = plane(2.0)
        mesh = scene.add_mesh("floor", pos, tri, uv, resolution=(16, 12))
        scene.add_light("SUN", power=strength, color=(1.0, 0.5, 0.25), matrix=rotation_x(theta))
        with scene.bake(photons=5_000_000, seed=5) as result:
            lm = result.lightmap(mesh)
    assert lm.rgb.shape == (12, 16, 3)
    truth = strength * math.cos(theta) / math.pi
    for c, colour in enumerate((1.0, 0.5, 0.25)):
        assert lm.rgb[..., c].mean() == pytest.approx(truth * colour, rel=0.01), c
    # error is the standard error of the mean RGB: mean colour 7/12.
    check_against_truth(lm, np.full(lm.error.shape, truth * 7 / 12), "sun")


def test_row_zero_is_v_zero():
    """Straight-down sun, a blocker over y < 0 (v < 0.5): the bottom half of the lightmap is dark."""
    strength, res = 2.0, 16
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.0)
        pos, tri, uv = plane(2.0)
        mesh = scene.add_mesh("floor", pos, tri, uv, resolution=res)
        blocker = np.array([[-3, -3, 1], [3, -3, 1], [3, 0, 1], [-3, 0, 1]], np.float32)
        scene.add_mesh("blocker", blocker, QUAD_TRIANGLES)
        scene.add_light("SUN", power=strength)  # identity matrix: shines along -Z
        with scene.bake(photons=200_000, seed=2) as result:
            lm = result.lightmap(mesh)
    m = lm.rgb.mean(axis=2)
    # Rows 7 and 8 touch the shadow edge (the sun's disc has a small angle): leave them out.
    assert np.all(m[: res // 2 - 1] == 0), m[: res // 2 - 1].max()
    assert m[res // 2 + 1:].mean() == pytest.approx(strength / math.pi, rel=0.02)


@pytest.mark.parametrize("kind, fields, flux", [
    ("POINT", dict(power=200.0, color=(1.0, 0.5, 0.0)), 200.0 * 0.5),
    # Cycles 3.x spot: intensity P / (4 pi) times cos(angle to the axis) inside the cone (times a
    # smoothstep over the blend zone), so with no blend the flux is P / 4 * sin^2(half angle).
    ("SPOT", dict(power=200.0, spot_size=math.radians(90), spot_blend=0.0), 200.0 / 4 * math.sin(math.radians(45)) ** 2),
    ("SPOT", dict(power=200.0, spot_size=math.radians(60), spot_blend=0.4), None),
    ("AREA_RECT", dict(power=100.0, size=2.0, size_y=0.5), math.pi * 100.0 / 4),
    ("AREA_DISK", dict(power=100.0, size=0.7), math.pi * 100.0 / 4),
])
def test_emitted_power_matches_cycles_units(kind, fields, flux):
    """Radiant flux of each light in Cycles' units: point P; spot P/(4 pi) x integral of its falloff
    (cos x smoothstep, as in Cycles' spot_light_attenuation); area radiance P / (4 A) one-sided: flux pi P / 4."""
    if flux is None:  # spot with blend: integrate Cycles' falloff over the sphere numerically
        cos_half = math.cos(fields["spot_size"] / 2)
        smooth = (1 - cos_half) * fields["spot_blend"]
        c = np.linspace(cos_half, 1, 200_001)
        x = np.clip((c - cos_half) / smooth, 0, 1)
        falloff = c * x * x * (3 - 2 * x)
        integral = 2 * math.pi * np.sum((falloff[1:] + falloff[:-1]) / 2 * np.diff(c))
        flux = fields["power"] / (4 * math.pi) * integral
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.5)
        pos, tri, uv = plane(2.0)
        scene.add_mesh("floor", pos, tri, uv, resolution=4)
        scene.add_light(kind, matrix=translation(0, 0, 1), **fields)
        with scene.bake(photons=20_000) as result:
            assert result.stats["emitted_power"] == pytest.approx(flux, rel=1e-3)


def test_area_light_irradiance_at_centre():
    """A small square area light of power P, side a, facing down at height h: radiance L = P / (4 a^2),
    irradiance below its centre E = 4 L * atan-formula (exact for a square over a parallel plane)."""
    power, a, h, res = 400.0, 0.5, 1.0, 32
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.0)
        pos, tri, uv = plane(2.0)
        mesh = scene.add_mesh("floor", pos, tri, uv, resolution=res)
        scene.add_light("AREA_RECT", power=power, size=a, matrix=translation(0, 0, h))
        with scene.bake(photons=10_000_000, max_bounces=0, seed=4) as result:
            lm = result.lightmap(mesh)
    radiance = power / (4 * a * a)

    def rect_irradiance(x0, x1, y0, y1):
        # Irradiance at the origin from a Lambertian rectangle [x0,x1]x[y0,y1] at height h (sum of corner terms).
        def f(x, y):
            return (x / math.sqrt(x * x + h * h) * math.atan(y / math.sqrt(x * x + h * h))
                    + y / math.sqrt(y * y + h * h) * math.atan(x / math.sqrt(y * y + h * h)))
        return radiance / 2 * (f(x1, y1) - f(x0, y1) - f(x1, y0) + f(x0, y0))

    half = a / 2

    def value(x, y):
        out = np.zeros(np.broadcast(x, y).shape)
        for idx in np.ndindex(out.shape):
            px, py = np.broadcast_to(x, out.shape)[idx], np.broadcast_to(y, out.shape)[idx]
            out[idx] = rect_irradiance(-half - px, half - px, -half - py, half - py) / math.pi
        return out

    # Central 8x8 texels, averaged over each texel's central half (the default texel value).
    c0 = res // 2 - 4
    truth = texel_average(value, -0.5, 0.5, -0.5, 0.5, 8, 8, sub=8, window=0.5, fold_quad=(-2.0, 2.0, -2.0, 2.0))
    centre = photonlm.Lightmap(*(a_[c0:c0 + 8, c0:c0 + 8] for a_ in lm))
    check_against_truth(centre, truth, "area light")
