"""Glass and metal in a room lit through a glazed window: photonlm vs a converged Cycles bake.

Scene (specular_scenes.glazed_room): a closed 4 x 4 x 2.5 m room of white Diffuse BSDF quads,
16 x 16 lightmaps (0.25 m texels), lit only through a 1.5 x 1.25 m window glazed with an 8 mm pane
(a quad with Solidify and a Glass BSDF of IOR 1.5): a sun of 20 degrees angle (elevation 35
degrees) and a uniform sky colour outside. Inside, a gold metal sphere (Principled BSDF, Metallic
1, roughness 0.2) and a glass sphere (Glass BSDF). All light in the room has passed the pane
(in and out of the glass) and part of it the spheres.

photonlm: bpy.ops.photonlm.bake() to a 1 % target, all bounces, the window's portal light on,
          Texel Value = Texel Average.
Cycles:   DIFFUSE, pass_filter {'DIRECT', 'INDIRECT'} (irradiance / pi), 32 bounces, no clamping,
          no Filter Glossy, at 2 x 2 texels per lightmap texel box-averaged (near a whole-texel
          average, as photonlm's Texel Average: the glass sphere focuses the sun into a spot
          smaller than a texel, whose value depends on the texel's footprint), two halves (seeds 1 and 2) averaged; the
          portal hidden (its shadow rays end on the glass: it slows Cycles down tenfold and adds
          nothing). Cycles reaches the room's light only by paths through the pane (its shadow rays
          stop at glass), hence the many samples.
Metric: relative RMS error sqrt(mean((ours - cycles)^2)) / mean(cycles) over the covered texels of
the six room surfaces, all channels, with the reference's own noise (estimated from its two
halves) removed in quadrature. Checks:
- that error is within 1.5 x photonlm's own error estimate + 2 % (the engine's noise, plus room for
  what both bakers do differently at hard edges: footprints at the sun patch's edges, the caustic
  reconstruction's radius at the sphere's focus);
- the mean of each surface within 3 % + 2 x the reference's noise on that mean;
- the same bake with the pane removed (an open window: some 8 % brighter, no Fresnel losses) and
  with the gold sphere made a grey diffuse ball are each clearly further from Cycles (so the
  test can fail when glass or metal are ignored).
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402
import specular_scenes as ss  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

RES = 16
CYCLES_SAMPLES = int(os.environ.get("PHOTONLM_TEST_CYCLES_SAMPLES", 8192))  # per half, per sub-texel
SUPERSAMPLE = 2
TARGET = 0.01
SLOPE, SLACK = 1.5, 0.02
MEAN_TOL = 0.03
WORSE_FACTOR = 1.5


def metric(ours, half_a, half_b, objects):
    """(relative RMS error with the reference's noise removed, raw error, reference noise,
    {name: (mean ours / mean ref, the reference mean's relative noise)})."""
    sq, var, ref, means = [], [], [], {}
    for o in objects:
        mask = scenes.layout_coverage(o, RES) > 0.999
        r = 0.5 * (half_a[o.name] + half_b[o.name])[mask]
        v = ((half_a[o.name] - half_b[o.name])[mask] ** 2) / 4.0
        x = ours[o.name][mask]
        sq.append(((x - r) ** 2).ravel())
        var.append(v.ravel())
        ref.append(r.ravel())
        means[o.name] = (float(x.mean()) / float(r.mean()), math.sqrt(float(v.sum())) / max(float(r.sum()), 1e-30))
    sq, var, ref = np.concatenate(sq), np.concatenate(var), np.concatenate(ref)
    m = float(ref.mean())
    raw = math.sqrt(float(sq.mean())) / m
    noise = math.sqrt(float(var.mean())) / m
    return math.sqrt(max(raw * raw - noise * noise, 0.0)), raw, noise, means


def main():
    scenes.setup_paths()
    checks = scenes.Checks("glazed_room_vs_cycles")
    objs = ss.glazed_room(res=RES, sun_angle=20.0)
    room = [objs[n] for n in ss.ROOM_SURFACES]
    portal = objs["WindowPortal"]
    portal.hide_render = True
    a, ta = scenes.cycles_bake(room, RES, {'DIRECT', 'INDIRECT'}, CYCLES_SAMPLES, seed=1, supersample=SUPERSAMPLE)
    b, tb = scenes.cycles_bake(room, RES, {'DIRECT', 'INDIRECT'}, CYCLES_SAMPLES, seed=2, supersample=SUPERSAMPLE)
    portal.hide_render = False
    print("Cycles: 2 x %d samples at %d x %d per texel in %.1f s" % (CYCLES_SAMPLES, SUPERSAMPLE, SUPERSAMPLE, ta + tb))
    bpy.context.scene.photonlm.texel_value = 'AREA'

    def bake(seed, target=TARGET):
        last = scenes.photonlm_bake(50_000_000, 1024, seed=seed, target_error=target)
        return {n: last["objects"][n]["rgb"] for n in ss.ROOM_SURFACES}, last["stats"], last

    ours, st, last = bake(3)
    err, raw, noise, means = metric(ours, a, b, room)
    est = st["error_estimate"]
    print("photonlm: %.2f s, %d photons, error estimate %.2f %%" % (st["seconds_total"], st["photons_emitted"],
                                                                  100 * est))
    print("relative RMS error vs Cycles %.2f %% (raw %.2f %%, the reference's noise %.2f %%)"
          % (100 * err, 100 * raw, 100 * noise))
    checks.check(not any("lobe left out" in t for _, t in last["reports"]), "every lobe reached the engine")
    checks.check(err <= SLOPE * est + SLACK, "relative RMS error %.2f %% <= %.1f x the estimate %.2f %% + %.0f %%"
                 % (100 * err, SLOPE, 100 * est, 100 * SLACK))
    for name, (ratio, ref_noise) in means.items():
        checks.check(abs(ratio - 1.0) <= MEAN_TOL + 2.0 * ref_noise, "%-10s mean ours / Cycles %.4f (reference "
                     "noise on the mean %.2f %%)" % (name, ratio, 100 * ref_noise))

    # Controls: ignoring the glass or the metal must be visible.
    objs["Pane"].hide_render = True
    open_window, _, _ = bake(3, 0.02)  # its error is several times that: a coarser bake shows it
    objs["Pane"].hide_render = False
    err_open = metric(open_window, a, b, room)[0]
    gold = objs["GoldBall"]
    gold_mat = gold.data.materials[0]
    gold.data.materials[0] = scenes.diffuse_material("grey_ball", (0.5, 0.5, 0.5))
    grey_ball, _, _ = bake(3, 0.02)
    gold.data.materials[0] = gold_mat
    err_grey = metric(grey_ball, a, b, room)[0]
    checks.check(err_open >= WORSE_FACTOR * err, "open window instead of the pane: %.2f %% (>= %.1f x %.2f %%)"
                 % (100 * err_open, WORSE_FACTOR, 100 * err))
    checks.check(err_grey >= WORSE_FACTOR * err, "grey diffuse ball instead of gold: %.2f %% (>= %.1f x %.2f %%)"
                 % (100 * err_grey, WORSE_FACTOR, 100 * err))
    checks.finish()


main()
