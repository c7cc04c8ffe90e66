"""A Sky Texture's sun disc casts Cycles' penumbra: the direct light across a sun shadow edge under a
Nishita sky, photonlm against Cycles.

Scene: a 1 x 1 m floor (64 x 64 texels of 1.56 cm, fixed lightmap layout) and, 3 m above it, the
edge of an 8 x 8 m plate whose sun shadow crosses the middle of the floor; a Nishita Sky Texture
with its sun disc (0.545 degrees) 35 degrees up, its light along -X, so the shadow edge runs along
the floor's V axis. The disc's penumbra is 8.7 cm wide on the floor (5.5 texels); in the world's
1024 x 512 map a pixel is 0.35 degrees, and the sun drawn from the map (box-filtered pixels read
bilinearly) casts one about twice as wide. The add-on makes the disc a sun lamp of its own
(export/world.py, split_sun), a uniform disc as wide as Cycles' limb-darkened one.
photonlm: bpy.ops.photonlm.bake() with Max Bounces 0 (direct light only) to a 0.5 % target.
Cycles:   DIFFUSE, pass_filter {'DIRECT'} (irradiance / pi), the world's importance map at 2048, two
          seeds of CYCLES_SAMPLES samples each.
Metric: the profile across the edge, each texel column averaged over the floor's 64 rows, relative to
Cycles' lit level (the mean of the 8 columns farthest on the lit side). Checks: the largest
difference of a column from Cycles' is within PROFILE_LIMIT of the lit level (measured in Blender
3.4.1: 1.2 % with the disc a sun lamp of its own, 9.6 % with the sun drawn from the map), and the
floor's mean within 1 % of Cycles'.

Run: PHOTONLM_LIBRARY=.../libphotonlm.so PHOTONLM_SOURCE_DIR=<repo> blender -b --factory-startup
     --python-exit-code 1 --python blend_tests/test_sky_sun_disc.py
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

RES = 64
HEIGHT = 3.0                 # the plate above the floor (m)
ELEVATION = math.radians(35.0)
CYCLES_SAMPLES = int(os.environ.get("PHOTONLM_TEST_CYCLES_SAMPLES", 512))  # per seed; two seeds
PROFILE_LIMIT = 0.03
MEAN_LIMIT = 0.01


def build():
    """The floor (baked) and the plate whose edge shades half of it; the Nishita sky."""
    mat = scenes.diffuse_material("mat_white", (0.8, 0.8, 0.8))
    floor = scenes.quads_object("floor", [((-0.5, -0.5, 0.0), (0.5, -0.5, 0.0), (0.5, 0.5, 0.0), (-0.5, 0.5, 0.0),
                                           (0.0, 0.0, 1.0, 1.0))], mat, RES)
    # The plate's edge at x = HEIGHT / tan(elevation): its shadow edge falls on x = 0.
    x0 = HEIGHT / math.tan(ELEVATION)
    plate = scenes.quads_object("plate", [((x0, -4.0, HEIGHT), (x0, 4.0, HEIGHT), (x0 + 8.0, 4.0, HEIGHT),
                                           (x0 + 8.0, -4.0, HEIGHT), (0.0, 0.0, 1.0, 1.0))], mat, 8)
    plate.photonlm.enabled = False  # blocks the light, gets no lightmap
    world = bpy.context.scene.world
    nt = world.node_tree
    sky = nt.nodes.new('ShaderNodeTexSky')
    sky.sky_type = scenes.physical_sky_type()
    sky.sun_disc = True
    sky.sun_elevation = ELEVATION
    sky.sun_rotation = math.radians(90.0)  # the sun towards +X (azimuth 90 degrees - rotation)
    bg = nt.nodes['Background']
    nt.links.new(sky.outputs['Color'], bg.inputs['Color'])
    bg.inputs['Strength'].default_value = 1.0
    world.cycles.sampling_method = 'MANUAL'
    world.cycles.sample_map_resolution = 2048
    return floor, plate


def main():
    scenes.setup_paths()
    checks = scenes.Checks("sky_sun_disc")
    scenes.clear_scene()
    floor, plate = build()
    bpy.context.view_layer.update()
    refs = [scenes.cycles_bake([floor], None, {'DIRECT'}, CYCLES_SAMPLES, seed=seed)[0]["floor"] for seed in (1, 2)]
    ref = 0.5 * (refs[0] + refs[1])
    last = scenes.photonlm_bake(0, 0, seed=3, target_error=0.005)
    ours = np.array(last["objects"]["floor"]["rgb"], np.float64)
    # Columns (U, along X) across the edge, each the mean over the rows (V) of the mean of RGB.
    p_ref, p_ours = ref.mean(axis=(0, 2)), ours.mean(axis=(0, 2))
    lit = float(p_ref[:8].mean())
    noise = float(np.abs(refs[0] - refs[1]).mean(axis=(0, 2)).max()) / 2.0 / lit
    diff = (p_ours - p_ref) / lit
    print("profile across the shadow edge, columns 24-40, relative to Cycles' lit level %.4f:" % lit)
    print("  Cycles   " + " ".join("%6.3f" % (v / lit) for v in p_ref[24:41]))
    print("  photonlm " + " ".join("%6.3f" % (v / lit) for v in p_ours[24:41]))
    print("  Cycles' own noise per column: up to %.2f %%; photonlm's error estimate %.2f %%"
          % (100 * noise, 100 * last["stats"]["error_estimate"]))
    worst = int(np.argmax(np.abs(diff)))
    checks.check(abs(diff[worst]) <= PROFILE_LIMIT,
                 "the largest difference of a column from Cycles' %.2f %% (column %d) within %.0f %% of the lit level"
                 % (100 * diff[worst], worst, 100 * PROFILE_LIMIT))
    ratio = float(ours.mean() / ref.mean())
    checks.check(abs(ratio - 1.0) <= MEAN_LIMIT, "mean ours / Cycles %.4f within %.0f %%" % (ratio, 100 * MEAN_LIMIT))
    checks.finish()


main()
