"""Speed against error with glass and metal: photonlm against Cycles in a room lit through a glazed
window, in headless Blender.

    PHOTONLM_LIBRARY=$PWD/build/lib/libphotonlm.so PHOTONLM_SOURCE_DIR=$PWD \
        blender -b --factory-startup --python docs/bench_glazed_room.py -- --out /tmp/bench_glazed [--quick]

Scene: blend_tests/specular_scenes.py glazed_room at 32 x 32 texels per surface (0.125 m): a closed
4 x 4 x 2.5 m white room lit only through a 1.5 x 1.25 m window glazed with an 8 mm pane (Solidify,
Glass BSDF IOR 1.5); a sun (20 degrees angle, 35 degrees up) and a uniform sky outside; a gold
metal sphere and a glass sphere on the floor. Only the six room surfaces are measured.

Cycles reaches this room's light only through paths that pass the pane (its shadow rays stop at
glass), so it is run the way that is fastest for it here: without the window's portal (its shadow
rays end on the glass; with it Cycles is some ten times slower for the same noise). photonlm keeps
the portal (its sun and sky photons are aimed through it).

Texel values: by default both bakers give texel-centre values (photonlm's Like Cycles: direct light
over the texel's central half; caustic photons, though, land over the whole texel). The glass sphere
focuses the sun into a spot smaller than a texel, where the two differ; --texel-average compares
whole-texel averages instead (Cycles at 2 x 2 sub-texels per texel box-averaged, the same samples
per texel; photonlm with Texel Value = Texel Average), which both converge to.

Reference, metric and timing as docs/bench_vs_cycles.py (whose code this uses): a Cycles DIFFUSE
bake (DIRECT + INDIRECT, no COLOR), 32 bounces, no clamping, as two independent halves whose
difference gives the reference's own noise, removed in quadrature from every measured error;
relative RMSE over the fully covered texels, all channels; operator wall times, median of
--repeats for bakes under 2 s. Time to reach 5 % and 2 %: log-log interpolation along each
method's (seconds, error) points, extrapolated as t ~ error^-2 past the last point (marked ~).
"""
import argparse
import os
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import bench_vs_cycles as bvc  # noqa: E402

sys.path.insert(0, os.path.join(bvc.SRC, "blend_tests"))
import scenes  # noqa: E402
import specular_scenes as ss  # noqa: E402

LEVELS = (0.05, 0.02)


def run(args, plan):
    scenes.clear_scene()
    objs = ss.glazed_room(res=args.res, sun_angle=20.0)
    objects = [objs[n] for n in ss.ROOM_SURFACES]
    portal = objs["WindowPortal"]
    out_lm = os.path.join(args.out, "lightmaps")
    os.makedirs(out_lm, exist_ok=True)

    ss_ = 2 if args.texel_average else 1

    def cycles(spp, seed):
        """spp samples per lightmap texel (with --texel-average spread over 2 x 2 sub-texels)."""
        portal.hide_render = True
        try:
            return bvc.cycles_bake(objects, max(1, spp // (ss_ * ss_)), seed, supersample=ss_)
        finally:
            portal.hide_render = False

    cycles(1, 0)  # warm-up
    if args.texel_average:
        bpy.context.scene.photonlm.texel_value = 'AREA'
    f = os.path.join(args.out, "ref_glazed_%d_%d_ss%d.npz" % (args.res, plan["ref_samples"], ss_))
    if args.reuse_ref and os.path.exists(f):
        z = np.load(f)
        half_a = {o.name: z["a_" + o.name] for o in objects}
        half_b = {o.name: z["b_" + o.name] for o in objects}
        ref_seconds = float(z["seconds"])
    else:
        half_a, ta = cycles(plan["ref_samples"] // 2, 1)
        half_b, tb = cycles(plan["ref_samples"] // 2, 2)
        ref_seconds = ta + tb
        np.savez(f, seconds=ref_seconds, **{"a_" + k: v for k, v in half_a.items()},
                 **{"b_" + k: v for k, v in half_b.items()})
    metric = bvc.Metric(objects, half_a, half_b)
    print("reference: Cycles %d samples in %.0f s, its noise %.2f %%" % (plan["ref_samples"], ref_seconds,
                                                                        100 * metric.ref_noise), flush=True)
    result = dict(description="glazed room (pane IOR 1.5, 8 mm), sun 4 W/m^2 20 deg + sky (0.4, 0.5, 0.7), "
                              "a gold and a glass sphere; %d x %d maps; %s" % (
                                  args.res, args.res, "texel averages (Cycles at 2 x 2 per texel, photonlm Texel "
                                  "Average)" if args.texel_average else "texel-centre values (Like Cycles)"),
                  objects=[dict(name=n, resolution=args.res, texels=metric.texels[n]) for n in metric.names],
                  reference=dict(samples=plan["ref_samples"], seconds=ref_seconds, noise=metric.ref_noise,
                                 edge_texels=sum(int(v.sum()) for v in metric.edge_sel.values()), supersample=ss_,
                                 mean=metric.mean_all),
                  cycles=[], photonlm=[])
    for spp in plan["cycles_samples"]:
        maps, sec = cycles(spp, 0)
        sec = bvc.median_seconds(sec, args.repeats, lambda: cycles(spp, 0)[1])
        m = metric(maps)
        result["cycles"].append(dict(setting="%d spp" % spp, samples=spp, seconds=sec, series="default",
                                     texel_average=None, **m))
        print("cycles   %6d spp  %8.2f s  error %6.2f %% (raw %6.2f)" % (spp, sec, 100 * m["error"], 100 * m["raw"]),
              flush=True)
    bvc.photonlm_bake(out_lm, target_error=0.1, seed=999)  # warm-up
    for i, (target, budget) in enumerate(plan["photonlm"]):
        maps, est, sec, st, warns = bvc.photonlm_bake(out_lm, target_error=target, time_budget=budget, seed=11 + i)
        sec = bvc.median_seconds(sec, args.repeats, lambda: bvc.photonlm_bake(
            out_lm, target_error=target, time_budget=budget, seed=11 + i)[2])
        m = metric(maps, est)
        result["photonlm"].append(dict(
            setting="target %g" % target, target_error=target, time_budget=budget, seconds=sec,
            seconds_engine=st["seconds_total"], seconds_export=st["seconds_export"],
            seconds_setup=st["seconds_setup"], seconds_trace=st["seconds_trace"], seconds_direct=st["seconds_direct"],
            photons=st["photons_emitted"], direct_samples=st["direct_samples"], rays=st["rays_traced"],
            reported=st["error_estimate"], reported_direct=st.get("error_direct"), warnings=warns,
            texel_average=None, **m))
        print("photonlm target %-6g %7.2f s  %d photons  error %6.2f %% (raw %6.2f)  reported %6.2f %%"
              % (target, sec, st["photons_emitted"], 100 * m["error"], 100 * m["raw"], 100 * st["error_estimate"]),
              flush=True)
    bvc.ERROR_LEVELS = LEVELS
    bvc.add_crossings(result)
    return result


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="bench_glazed_room.py")
    ap.add_argument("--out", default="/tmp/bench_glazed")
    ap.add_argument("--quick", action="store_true", help="a small reference and fewer settings (development)")
    ap.add_argument("--res", type=int, default=32, help="texels per side of each surface's lightmap")
    ap.add_argument("--ref-samples", type=int, default=0, help="override the reference sample count")
    ap.add_argument("--reuse-ref", action="store_true", help="reuse a cached reference from --out")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--texel-average", action="store_true",
                    help="compare texel averages: every Cycles bake at 2 x 2 sub-texels per texel (the same "
                         "samples per texel), photonlm with Texel Value = Texel Average")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    os.environ.setdefault("PHOTONLM_TEST_OUT", args.out)
    lib_info = bvc.snapshot_library(args.out)
    scenes.setup_paths()
    bvc._hook_bridge()
    if args.quick:
        plan = dict(ref_samples=4096, cycles_samples=(16, 64, 256, 1024), photonlm=[(0.08, 60.0), (0.04, 60.0)])
    else:
        plan = dict(ref_samples=65536, cycles_samples=(64, 256, 1024, 4096, 16384, 32768),
                    photonlm=[(0.08, 120.0), (0.05, 120.0), (0.03, 120.0), (0.02, 120.0), (0.015, 120.0),
                              (0.01, 240.0)])
    if args.ref_samples:
        plan["ref_samples"] = args.ref_samples
    t0 = time.perf_counter()
    result = run(args, plan)
    results = dict(machine=dict(cpus=os.cpu_count(), blender=bpy.app.version_string), library=lib_info,
                   plan=dict(ref_samples=plan["ref_samples"], cycles_samples=list(plan["cycles_samples"]),
                             photonlm=[list(p) for p in plan["photonlm"]]),
                   scenes=dict(glazed=result), seconds_total=time.perf_counter() - t0)
    bvc.write_results(args.out, "bench_glazed_room", results, bvc.markdown("glazed", result))


if __name__ == "__main__":
    main()
