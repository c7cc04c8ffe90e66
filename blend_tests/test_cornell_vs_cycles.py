"""Cornell box, full global illumination: photonlm vs a converged Cycles bake.

Scene (blend_tests/scenes.py cornell_box): a 2 m box of five walls (white floor, ceiling and
back, red left, green right), two white boxes, a 0.5 m square area light (40 W) under the
ceiling. Every object has its own Diffuse BSDF material and a fixed 32 x 32 lightmap layout.

photonlm: bpy.ops.photonlm.bake(), all bounces (max_bounces 1024).
Cycles:   DIFFUSE, pass_filter {'DIRECT', 'INDIRECT'} (irradiance / pi), 32 bounces (diffuse 32),
          no clamping, 1024 samples, CPU.
Metric per object: mean(|ours - cycles|) / mean(cycles) over covered texels; must be < 5 %.
Also: the coverage-weighted mean of each object (its average irradiance / pi) within 1.5 %.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

RES = 32
PHOTONS = int(os.environ.get("PHOTONLM_TEST_PHOTONS", 30_000_000))
CYCLES_SAMPLES = int(os.environ.get("PHOTONLM_TEST_CYCLES_SAMPLES", 1024))
LIMIT = 0.05
MEAN_LIMIT = 0.015


def main():
    scenes.setup_paths()
    checks = scenes.Checks("cornell_vs_cycles")
    scenes.clear_scene()
    objs = scenes.cornell_box(resolution=RES)
    meshes = [objs[n] for n in scenes.CORNELL_OBJECTS]
    print("metric: mean(|ours - cycles|) / mean(cycles) over covered texels, per object; limit %.0f %%. "
          "Cycles %d samples, 32 bounces, no clamp; photonlm %d photons" % (100 * LIMIT, CYCLES_SAMPLES, PHOTONS))
    ref, t_cycles = scenes.cycles_bake(meshes, RES, {'DIRECT', 'INDIRECT'}, CYCLES_SAMPLES, bounces=32)
    last = scenes.photonlm_bake(PHOTONS, 1024, seed=11)
    st = last["stats"]
    print("times: photonlm %.2f s (%.2f M photons/s, %d photons, %d rays, export %.3f s, operator wall %.2f s); "
          "Cycles %.2f s for 7 maps" % (st["seconds_total"], st["photons_per_second"] / 1e6, st["photons_emitted"],
                                        st["rays_traced"], st["seconds_export"], last["wall_seconds"], t_cycles))
    for name in scenes.CORNELL_OBJECTS:
        ours = last["objects"][name]
        cov = scenes.layout_coverage(objs[name], RES)
        mask = cov > 0.999
        checks.check(int(((ours["coverage"] > 0.999) != mask).sum()) == 0,
                     "%-9s engine coverage matches the UV layout (%d covered texels)" % (name, int(mask.sum())))
        err = scenes.mean_relative_error(ours["rgb"], ref[name], mask)
        m_ours = scenes.coverage_weighted_mean(ours["rgb"], cov).mean()
        m_ref = scenes.coverage_weighted_mean(ref[name], cov).mean()
        checks.check(err < LIMIT, "%-9s error %.2f %% (limit %.0f %%)" % (name, 100 * err, 100 * LIMIT))
        checks.check(abs(m_ours / m_ref - 1) < MEAN_LIMIT, "%-9s mean ours %.4f cycles %.4f (ratio %.4f)"
                     % (name, m_ours, m_ref, m_ours / m_ref))
    checks.finish()


main()
