"""Each light type alone over a diffuse plane, direct light only: photonlm vs Cycles.

photonlm: bpy.ops.photonlm.bake() with max_bounces = 0 (direct light only).
Cycles:   bpy.ops.object.bake(type='DIFFUSE', pass_filter={'DIRECT'}), 1024 samples, CPU.
Both hold irradiance / pi. Metric: mean relative error = mean(|ours - cycles|) / mean(cycles)
over the texels covered by the plane (all RGB channels). Must be below 2 % for every light.
Emissive meshes: a plain quad, and one whose Emission Color is an image (half black, half white).

The plane is 2 m x 2 m at z = 0 facing +z with a 16 x 16 lightmap whose UV layout is the
plane's xy extent (fixed, not unwrapped).

Run: PHOTONLM_LIBRARY=.../libphotonlm.so PHOTONLM_SOURCE_DIR=<repo> blender -b --factory-startup
     --python-exit-code 1 --python blend_tests/test_lights_vs_cycles.py
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import numpy as np  # noqa: E402

RES = 16
PHOTONS = int(os.environ.get("PHOTONLM_TEST_PHOTONS", 20_000_000))
CYCLES_SAMPLES = 1024
LIMIT = 0.02


def light_cases():
    """name -> function building the emitter (the plane exists already). Returns objects that
    must not get a lightmap (emissive geometry)."""
    def point():
        scenes.add_light("point", 'POINT', (0.2, 0.1, 1.0), energy=100.0, shadow_soft_size=0.25)

    def spot():
        scenes.add_light("spot", 'SPOT', (-0.1, 0.15, 1.2), rotation=(math.radians(8), 0, 0),
                         energy=200.0, shadow_soft_size=0.1, spot_size=math.radians(60), spot_blend=0.15)

    def sun():
        scenes.add_light("sun", 'SUN', (0, 0, 3), rotation=(math.radians(30), math.radians(10), 0),
                         energy=3.0, angle=math.radians(5))

    def area_rect():
        scenes.add_light("area_rect", 'AREA', (-0.1, 0.2, 0.9), rotation=(math.radians(20), 0, 0),
                         energy=60.0, shape='RECTANGLE', size=0.6, size_y=0.4)

    def area_disk():
        scenes.add_light("area_disk", 'AREA', (0.25, -0.2, 0.7), rotation=(0, math.radians(-25), 0),
                         energy=40.0, shape='DISK', size=0.5)

    def emissive_quad():
        mat = scenes.emission_material("quad_emission", (1.0, 0.9, 0.7), 8.0)
        h = 0.25
        quad = scenes.quads_object("emitter", [((-h, h, 0.8), (h, h, 0.8), (h, -h, 0.8), (-h, -h, 0.8),
                                                (0, 0, 1, 1))], mat, 0)
        quad.photonlm.enabled = False  # geometry (an emitter), no lightmap
        return [quad]

    def textured_quad():
        # Emission looked up per point: an image white over one half of the quad, black over the
        # other, split across the quad's diagonal (a per-triangle mean would light the plane wrongly).
        import bpy
        mat = scenes.emission_material("textured_emission", (1.0, 1.0, 1.0), 6.0)
        img = bpy.data.images.new("half_white", 64, 64, alpha=True)  # byte sRGB: 0 and 1 are exact
        px = np.zeros((64, 64, 4), np.float32)
        px[32:, :, :3] = 1.0  # rows from the bottom: v > 0.5 is white
        px[..., 3] = 1.0
        img.pixels.foreach_set(px.ravel())
        nt = mat.node_tree
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image = img
        tex.interpolation = 'Linear'
        nt.links.new(tex.outputs["Color"], nt.nodes["Emission"].inputs["Color"])
        h = 0.5
        quad = scenes.quads_object("emitter", [((-h, h, 0.8), (h, h, 0.8), (h, -h, 0.8), (-h, -h, 0.8),
                                                (0, 0, 1, 1))], mat, 0)
        quad.photonlm.enabled = False
        return [quad]

    def world():
        scenes.set_world_color((0.4, 0.5, 0.6), 1.5)

    return [("point", point), ("spot", spot), ("sun", sun), ("area_rect", area_rect),
            ("area_disk", area_disk), ("emissive_quad", emissive_quad), ("textured_quad", textured_quad),
            ("world", world)]


def main():
    scenes.setup_paths()
    checks = scenes.Checks("lights_vs_cycles")
    print("metric: mean(|ours - cycles|) / mean(cycles) over covered texels; limit %.0f %%; "
          "%d photons per light, Cycles %d samples, lightmap %dx%d" % (100 * LIMIT, PHOTONS, CYCLES_SAMPLES,
                                                                      RES, RES))
    rows = []
    for name, build in light_cases():
        scenes.clear_scene()
        plane = scenes.plane("plane", scenes.diffuse_material("plane_mat", (0.8, 0.8, 0.8)), resolution=RES)
        build()
        ref, t_cycles = scenes.cycles_bake([plane], RES, {'DIRECT'}, CYCLES_SAMPLES)
        last = scenes.photonlm_bake(PHOTONS, 0, seed=7)
        ours = last["objects"]["plane"]
        mask = ours["coverage"] > 0.999
        err = scenes.mean_relative_error(ours["rgb"], ref["plane"], mask)
        st = last["stats"]
        ratio = float(ours["rgb"][mask].mean() / max(ref["plane"][mask].mean(), 1e-30))
        rows.append((name, err, ratio, st["seconds_total"], t_cycles))
        checks.check(err < LIMIT, "%-13s error %.2f %% (mean ours/cycles %.4f) | ours %.2f s (%.1f M photons/s, "
                     "%d hits) | cycles %.2f s | %d texels" % (
                         name, 100 * err, ratio, st["seconds_total"], st["photons_per_second"] / 1e6,
                         st["photon_hits"], t_cycles, int(mask.sum())))
        if name == "textured_quad":  # the image's lit half lights its side of the plane: the test can fail
            rows_ref = ref["plane"].mean(axis=(1, 2))
            lo, hi = sorted((float(rows_ref[:RES // 2].mean()), float(rows_ref[RES // 2:].mean())))
            checks.check(hi > 1.5 * lo, "textured_quad: Cycles' plane halves differ (%.4f vs %.4f)" % (hi, lo))
        if name == "world":  # analytic: a plane under a uniform world sees radiance L everywhere
            want = np.array((0.4, 0.5, 0.6), np.float32) * 1.5
            err_a = float(np.abs(ours["rgb"][mask] - want).mean() / want.mean())
            err_c = float(np.abs(ref["plane"][mask] - want).mean() / want.mean())
            checks.check(err_a < LIMIT, "world analytic (value = colour x strength): ours %.2f %%, cycles %.2f %%"
                         % (100 * err_a, 100 * err_c))
    print("summary (light, error %, mean ratio ours/cycles, ours s, cycles s):")
    for r in rows:
        print("  %-13s %6.2f %%  %.4f  %6.2f s  %6.2f s" % (r[0], 100 * r[1], r[2], r[3], r[4]))
    checks.finish()


main()
