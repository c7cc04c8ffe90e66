"""Error per object in the artist's room: photonlm's bakes against a Cycles reference, in
headless Blender.

    PHOTONLM_TEST_OUT=/tmp/bench_artist scripts/blender.sh 5.2 -b --factory-startup --python-exit-code 1 \
        --python docs/bench_artist_room.py -- --out /tmp/bench_artist [--targets 0.03,0.01] [--quick]

(or, with the Blender on the PATH: PHOTONLM_LIBRARY=$PWD/build/lib/libphotonlm.so PHOTONLM_SOURCE_DIR=$PWD
blender -b --factory-startup --python docs/bench_artist_room.py -- --out /tmp/bench_artist). In a
Blender run in its own root (scripts/blender.sh 4.3 or 5.2) only the checkout and $PHOTONLM_TEST_OUT
are seen: give --out inside one of them. The engine library is copied into --out first, so that a
rebuild during the run changes nothing; the JSON records which build it was.

Scene: blend_tests/scenes.py artist_room, the room as an artist builds it: Solidify and Boolean
walls with a window, Array, Mirror, Bevel, Subdivision Surface, a textured floor, a sun through the
window and a uniform sky; no lightmap UV maps of its own. The add-on makes them at the first bake
(a warm-up of a fixed 1 M photons, timed and reported apart) and chooses each object's resolution
from the scene's texel density; everything else is the add-on's default (Max Photons included:
--photon-cap changes it, 0 = none; --max-bounces 63 bakes from photons alone, without the final
gather) but the target and the seed.

Per target (--targets, default 0.03): the operator wall time of bpy.ops.photonlm.bake (export, UV
maps reused, direct pass, photons, EXR write-back, material wiring) and the engine's figures,
among them error_worst (the largest per-object estimate, what the target bounds) where the engine
reports it.

Reference: Cycles DIFFUSE bake, pass filter DIRECT + INDIRECT (no COLOR: irradiance / pi), 32
bounces, no clamping, box pixel filter one texel wide, into the same 'lightmap' UV maps at the same
resolutions, as two independent halves (seeds 1 and 2). Their difference estimates the reference's
own noise, printed per object and removed in quadrature from every measured error.

Cycles' noise differs a hundredfold between the objects here: the sunlit outside of the walls is
clean after a few samples, the books in the dark corner (lit only by light bounced from the sun's
patch on the floor) are at some 40 % per texel after 512 samples (a portal in the window lowers
Cycles' variance there by about 2x, at 2.3x the time: not used). So by default the samples are
shared out per object: a pilot of 32 samples per texel measures each object's noise per sample
and the texel samples per second, then each object gets the samples that give every object the
same noise in --ref-seconds of baking (default 900; at least 64 samples each).
On a machine of 2 shared cores that noise is a few per cent, not under 1 %: well above what would
vanish, but removed in quadrature it leaves the measurement unbiased; its standard error is
printed with it (the texels taken as independent: a lower bound). --ref-samples N gives every
object N samples instead. The reference is cached in --out, keyed by --ref-seconds (or N) and the
Blender version, with a hash of the UV maps and their sizes (a rerun with other targets reuses
it; changed maps bake it again). The automatic UV maps differ slightly each time they are made,
so the first run also saves the room with its maps (artist_room_b<version>.blend in --out) and
later runs open it instead of building the room again. Suzanne is refined by the engine (OpenSubdiv on the cage) and by
Blender's Subdivision Surface for Cycles: the two surfaces differ slightly.

Texels: those fully covered (coverage > 0.999) both in the evaluated mesh's lightmap UV map (what
Cycles bakes) and in the engine's coverage of its map.

Per object, over those texels, on grey values (the per-texel mean of R, G, B, what photonlm's
estimate describes):
  estimate  the engine's own estimate for the object, from the lightmap's error channel (standard
            error of the texel's mean RGB): sqrt(mean(err^2)) / mean(value) (the add-on records
            no per-object figure; the JSON's estimate_covered is the same over every texel the
            engine covers at all, as the engine's error_worst is defined);
  measured  sqrt(mean((x - ref)^2)) / mean(ref), the reference's noise removed in quadrature;
  ratio     mean(x) / mean(ref) (bias);
  ref noise the reference's own relative RMS noise, sqrt(mean((a - b)^2 / 4)) / mean(ref).
The same over all texels of all objects together (scene-wide), the worst object, and in the JSON
also the RGB error and the error away from hard edges (docs/bench_vs_cycles.py's edge mask).

Writes bench_artist_room.json and bench_artist_room.md to --out, the reference cache
ref_artist_room_*.npz and per target maps_<target>.npz (photonlm's maps and error channels, the
masks). Timings are wall-clock on whatever else the machine is doing.
"""
import argparse
import hashlib
import json
import math
import os
import sys
import time
import warnings

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(HERE)
sys.path.insert(0, os.path.join(SRC, "blend_tests"))
sys.path.insert(0, HERE)
import scenes  # noqa: E402
import bench_vs_cycles as bvc  # noqa: E402

NAMES = scenes.ARTIST_ROOM_OBJECTS
FULL = 0.999  # coverage of a fully covered texel
WARMUP_PHOTONS = 1_000_000
PILOT_SAMPLES = 32  # the reference's pilot: samples per texel, both halves together
MIN_SAMPLES = 64    # the least reference samples per texel of any object


# ---- coverage ------------------------------------------------------------------------------------

def evaluated_uvs(objects):
    """Each object's evaluated 'lightmap' UV triangles (T, 3, 2) (None where it has none)."""
    return {o.name: scenes.evaluated_lightmap_triangles(o, world=False)[1] for o in objects}


def uv_hash(uvs, sizes):
    h = hashlib.sha256()
    for n in sorted(uvs):
        h.update(n.encode())
        h.update(np.asarray(sizes[n], np.int64).tobytes())
        h.update(np.ascontiguousarray(uvs[n], np.float32).tobytes())
    return h.hexdigest()[:16]


# ---- bakes ---------------------------------------------------------------------------------------

def photonlm_bake(target, seed, photons):
    """One bake through the add-on's operator with its defaults, at `target` (0: exactly `photons`;
    else `photons` is the cap, None = the add-on's). Returns (record.last() with "wall_seconds",
    {name: rgb (h, w, 3)}, {name: error (h, w)}, {name: coverage (h, w)})."""
    s = bpy.context.scene.photonlm
    last = scenes.photonlm_bake(s.photons if photons is None else photons, s.max_bounces, seed=seed,
                                target_error=target)
    pl = scenes.setup_paths().bridge.get()
    rgb, err, cov = {}, {}, {}
    for n in NAMES:
        o = last["objects"][n]
        if o.get("rgb") is None or o.get("error") is None:  # large maps: read the EXR
            lm = pl.read_lightmap_exr(o["path"])
            rgb[n], err[n] = np.array(lm.rgb, np.float64), np.array(lm.error, np.float64)
        else:
            rgb[n], err[n] = np.array(o["rgb"], np.float64), np.array(o["error"], np.float64)
        cov[n] = np.array(o["coverage"], np.float64)
    return last, rgb, err, cov


def cycles_halves(objects, sizes, spp):
    """scenes.cycles_bake of `objects` at their lightmap sizes, spp samples, seeds 1 and 2 (the two
    halves). Returns (a, b, seconds)."""
    saved = {o.name: o.photonlm.resolution for o in objects}
    try:
        for o in objects:  # scenes.cycles_bake bakes at photonlm.resolution (0 = Auto here)
            o.photonlm.resolution = sizes[o.name][0]
        a, ta = scenes.cycles_bake(objects, None, ("DIRECT", "INDIRECT"), spp, bounces=32, seed=1)
        b, tb = scenes.cycles_bake(objects, None, ("DIRECT", "INDIRECT"), spp, bounces=32, seed=2)
    finally:
        for o in objects:
            o.photonlm.resolution = saved[o.name]
    return a, b, ta + tb


def half_noise(a, b, mask):
    """Relative RMS noise of one half (grey) over `mask`: sqrt(mean((a - b)^2 / 2)) / mean."""
    d = (a - b).mean(axis=2)[mask]
    return math.sqrt(float((d ** 2).mean()) / 2.0) / max(float((0.5 * (a + b)).mean(axis=2)[mask].mean()), 1e-30)


def allocate(sigma, texels, rate, seconds, least=MIN_SAMPLES):
    """Samples per texel (both halves together) for each object: sigma[n] / sqrt(samples) = x, the
    same noise x on every object, rounded up to an even count and at least `least`, with x as low as
    `seconds` of baking at `rate` texel samples per second allows."""
    def counts(x):
        return {n: max(least, 2 * math.ceil(sigma[n] ** 2 / x ** 2 / 2.0)) for n in sigma}

    def cost(x):
        c = counts(x)
        return sum(texels[n] * c[n] for n in sigma) / rate
    lo, hi = 1e-5, 10.0
    for _ in range(100):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if cost(mid) > seconds else (lo, mid)
    return counts(hi)


def cycles_reference(objects, sizes, masks, texels, out, uvs, samples=0, seconds=0.0):
    """The reference's two halves, cached in `out`. samples > 0: that many samples per texel (both
    halves together) on every object; else a pilot of PILOT_SAMPLES measures each object's noise
    per sample (over `masks`) and the texel samples per second (texels: each object's texels in its
    UV islands, what Cycles bakes), and allocate() shares `seconds` of baking. Objects with the same
    count are baked together. Returns (a, b, info)."""
    key = uv_hash(uvs, sizes)
    mode = ("s%d" % samples) if samples else ("t%g" % seconds)
    path = os.path.join(out, "ref_artist_room_%s_b%s.npz" % (mode, bpy.app.version_string.split()[0]))
    if os.path.exists(path):
        z = np.load(path, allow_pickle=False)
        if str(z["uv_hash"]) == key:
            info = json.loads(str(z["info"]))
            print("reference: reused %s (%.0f s when baked)" % (path, info["seconds"]), flush=True)
            return ({n: z["a_" + n] for n in NAMES}, {n: z["b_" + n] for n in NAMES}, dict(info, reused=True))
        print("reference: %s is for other UV maps or sizes: baking again" % path, flush=True)
    info = dict(mode=mode, pilot_seconds=None, sigma=None)
    if samples:
        counts = {n: samples for n in NAMES}
    else:
        pa, pb, pt = cycles_halves(objects, sizes, PILOT_SAMPLES // 2)
        sigma = {n: half_noise(pa[n], pb[n], masks[n]) * math.sqrt(PILOT_SAMPLES // 2) for n in NAMES}
        rate = sum(texels.values()) * PILOT_SAMPLES / pt
        counts = allocate(sigma, texels, rate, seconds)
        info.update(pilot_seconds=pt, sigma=sigma, rate=rate,
                    planned_seconds=sum(texels[n] * counts[n] for n in NAMES) / rate)
        print("reference pilot (%d samples): %.1f s, %.2f M texel samples/s; noise per sample: %s"
              % (PILOT_SAMPLES, pt, rate / 1e6, ", ".join("%s %.2f" % (n, sigma[n]) for n in NAMES)), flush=True)
    a, b, total = {}, {}, 0.0
    for spp in sorted(set(counts.values())):
        group = [o for o in objects if counts[o.name] == spp]
        ga, gb, t = cycles_halves(group, sizes, max(1, spp // 2))
        a.update(ga)
        b.update(gb)
        total += t
        print("reference: %s at %d samples (2 x %d): %.1f s"
              % (", ".join(o.name for o in group), spp, spp // 2, t), flush=True)
    info.update(samples=counts, seconds=total)
    np.savez(path + ".tmp.npz", uv_hash=key, info=json.dumps(info),
             **{"a_" + k: v for k, v in a.items()}, **{"b_" + k: v for k, v in b.items()})
    os.replace(path + ".tmp.npz", path)
    return a, b, dict(info, reused=False)


# ---- metrics -------------------------------------------------------------------------------------

class Reference:
    """The reference's grey values, RGB values and noise variances over each object's measured texels."""

    def __init__(self, a, b, masks):
        self.masks = masks
        self.ref = {n: 0.5 * (a[n] + b[n]) for n in NAMES}
        self.rgb = {n: self.ref[n][masks[n]] for n in NAMES}                       # (k, 3)
        self.grey = {n: self.rgb[n].mean(axis=1) for n in NAMES}                   # (k,)
        self.var_rgb = {n: ((a[n] - b[n]) ** 2 / 4.0)[masks[n]] for n in NAMES}
        self.var_grey = {n: ((a[n] - b[n]).mean(axis=2) ** 2 / 4.0)[masks[n]] for n in NAMES}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN neighbourhoods outside the islands
            edges = {n: bvc.edge_mask(self.ref[n], masks[n], math.sqrt(float(self.var_grey[n].mean())))
                     for n in NAMES}
        self.smooth = {n: ~edges[n][masks[n]] for n in NAMES}
        self.noise = {n: math.sqrt(float(self.var_grey[n].mean())) / float(self.grey[n].mean()) for n in NAMES}
        allg = np.concatenate([self.grey[n] for n in NAMES])
        self.noise_all = math.sqrt(float(np.concatenate([self.var_grey[n] for n in NAMES]).mean())) / float(allg.mean())


def _corrected(sq, var, mean):
    raw = math.sqrt(float(sq.mean())) / mean
    noise = math.sqrt(float(var.mean())) / mean
    return raw, math.sqrt(max(raw * raw - noise * noise, 0.0))


def _standard_error(sq, var, mean, error):
    """Standard error of the corrected error, from the spread of the texels' (x - ref)^2 - noise^2
    taken as independent (neighbouring texels are not quite: a lower bound)."""
    q = (sq - var) / (mean * mean)
    se2 = float(q.std()) / math.sqrt(max(q.size, 1))
    return se2 / (2.0 * error) if error > math.sqrt(se2) else math.sqrt(se2)


def measure(ref, rgb, err, names):
    """Figures over the measured texels of `names` together (see the module text)."""
    sel = lambda d, k=None: np.concatenate([d[n] if k is None else d[n][k[n]] for n in names])  # noqa: E731
    x = {n: rgb[n][ref.masks[n]] for n in names}
    xg = {n: x[n].mean(axis=1) for n in names}
    e = sel({n: err[n][ref.masks[n]] for n in names})
    g, rg = sel(xg), sel(ref.grey)
    mean_ref = float(rg.mean())
    raw, measured = _corrected((g - rg) ** 2, sel(ref.var_grey), mean_ref)
    measured_se = _standard_error((g - rg) ** 2, sel(ref.var_grey), mean_ref, measured)
    raw_rgb, measured_rgb = _corrected(np.concatenate([((x[n] - ref.rgb[n]) ** 2).ravel() for n in names]),
                                       np.concatenate([ref.var_rgb[n].ravel() for n in names]),
                                       float(np.concatenate([ref.rgb[n].ravel() for n in names]).mean()))
    dg = {n: (xg[n] - ref.grey[n]) ** 2 for n in names}
    _, smooth = _corrected(sel(dg, ref.smooth), sel(ref.var_grey, ref.smooth), mean_ref)
    return dict(texels=int(g.size), estimate=math.sqrt(float((e ** 2).mean())) / float(g.mean()),
                measured=measured, measured_se=measured_se, raw=raw, measured_rgb=measured_rgb, raw_rgb=raw_rgb,
                smooth=smooth,
                mean_ratio=float(g.mean()) / mean_ref, mean_ref=mean_ref,
                ref_noise=math.sqrt(float(sel(ref.var_grey).mean())) / mean_ref,
                sq_error=float(((g - rg) ** 2).sum()))


def engine_estimate_covered(rgb, err, cov):
    """The same estimate over every texel the engine counts as covered (coverage > 0)."""
    k = cov > 0.0
    return math.sqrt(float((err[k] ** 2).mean())) / float(rgb[k].mean(axis=1).mean())


# ---- output --------------------------------------------------------------------------------------

def _pct(v):
    return "-" if v is None else "%.2f %%" % (100.0 * v)


def markdown(r):
    ref = r["reference"]
    pilot = "" if ref.get("pilot_seconds") is None else " + pilot %.0f s" % ref["pilot_seconds"]
    lines = ["### The artist's room: photonlm against Cycles, per object", "",
             "Blender %s, %d CPUs. Reference: Cycles, %.0f s%s%s (samples per texel per object below, two "
             "halves), its noise %s scene-wide, removed in quadrature. Warm-up bake (makes the UV maps): "
             "%.1f s. Errors on grey values (mean of R, G, B) over the fully covered texels; measured +- its "
             "standard error (texels taken as independent)."
             % (r["machine"]["blender"], r["machine"]["cpus"], ref["seconds"], pilot,
                ", cached" if ref["reused"] else "", _pct(ref["noise"]), r["warmup"]["seconds"])]
    for t in r["targets"]:
        s = t["scene"]
        e = t["engine"]
        worst_est = "" if e.get("error_worst") is None else ", its worst object %s %s" % (
            e.get("error_worst_object"), _pct(e["error_worst"]))
        lines += ["", "**Target %g**: %.1f s (engine %.1f s, export %.1f s), %.1f M photons, engine's estimate "
                  "%s%s; scene-wide: estimate %s, measured %s, mean ratio %.4f; worst object measured: %s (%s)."
                  % (t["target"], t["seconds"], e["seconds_total"], e["seconds_export"],
                     e["photons_emitted"] / 1e6, _pct(e["error_estimate"]), worst_est,
                     _pct(s["estimate"]), _pct(s["measured"]), s["mean_ratio"], t["worst"],
                     _pct(t["objects"][t["worst"]]["measured"])), "",
                  "| object | size | texels | estimate | measured | estimate / measured | mean ratio "
                  "| ref samples | ref noise |", "|---|---|---|---|---|---|---|---|---|"]
        for n in NAMES:
            o = t["objects"][n]
            lines.append("| %s | %d | %d | %s | %s +- %.2f | %.2f | %.4f | %d | %s |"
                         % (n, r["sizes"][n][0], o["texels"], _pct(o["estimate"]), _pct(o["measured"]),
                            100 * o["measured_se"], o["estimate"] / max(o["measured"], 1e-12), o["mean_ratio"],
                            ref["samples"][n], _pct(o["ref_noise"])))
        lines.append("| all | | %d | %s | %s +- %.2f | %.2f | %.4f | | %s |"
                     % (s["texels"], _pct(s["estimate"]), _pct(s["measured"]), 100 * s["measured_se"],
                        s["estimate"] / max(s["measured"], 1e-12), s["mean_ratio"], _pct(s["ref_noise"])))
    return "\n".join(lines)


# ---- driver --------------------------------------------------------------------------------------

def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="bench_artist_room.py")
    ap.add_argument("--out", default="/tmp/bench_artist")
    ap.add_argument("--targets", default="0.03", help="comma-separated target errors")
    ap.add_argument("--ref-seconds", type=float, default=900.0,
                    help="seconds of Cycles baking shared among the objects for the reference (--quick: 120)")
    ap.add_argument("--ref-samples", type=int, default=0,
                    help="instead: this many reference samples per texel on every object (both halves together)")
    ap.add_argument("--quick", action="store_true", help="a small reference (development)")
    ap.add_argument("--max-bounces", type=int, default=None,
                    help="Max Bounces for the measured bakes (63: photons alone, no final gather)")
    ap.add_argument("--photon-cap", type=int, default=None,
                    help="Max Photons (default: the add-on's; 0 = none, the target decides)")
    args = ap.parse_args(argv)
    targets = [float(t) for t in args.targets.split(",") if t.strip()]
    ref_seconds = 120.0 if args.quick else args.ref_seconds
    os.makedirs(args.out, exist_ok=True)
    os.environ.setdefault("PHOTONLM_TEST_OUT", args.out)
    t_start = time.perf_counter()
    lib_info = bvc.snapshot_library(args.out)
    scenes.setup_paths()
    # The room with the UV maps of the first run, so that the cached reference fits them (the
    # automatic UV maps differ from one making to the next).
    blend = os.path.join(args.out, "artist_room_b%s.blend" % bpy.app.version_string.split()[0])
    if os.path.exists(blend):
        bpy.ops.wm.open_mainfile(filepath=blend)
        print("scene: %s (its UV maps)" % blend, flush=True)
    else:
        scenes.clear_scene()
        scenes.artist_room(scenes.out_dir("artist_room_textures"))
    objects = [bpy.data.objects[n] for n in NAMES]
    scene = bpy.context.scene
    scene.photonlm.output_dir = os.path.join(args.out, "lightmaps")

    addon_photons = scene.photonlm.photons  # the add-on's Max Photons, before the warm-up sets its own
    cap = addon_photons if args.photon_cap is None else args.photon_cap
    last, _, _, engine_cov = photonlm_bake(0.0, 999, WARMUP_PHOTONS)
    warmup = dict(photons=WARMUP_PHOTONS, seconds=last["wall_seconds"],
                  seconds_export=float(last["stats"]["seconds_export"]))
    print("warm-up bake (%d photons, UV maps made): %.1f s (export %.1f s)"
          % (WARMUP_PHOTONS, warmup["seconds"], warmup["seconds_export"]), flush=True)
    if not os.path.exists(blend):
        photons = scene.photonlm.photons
        scene.photonlm.photons = addon_photons  # the settings as before the warm-up
        bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
        scene.photonlm.photons = photons
    sizes = {n: tuple(int(v) for v in last["objects"][n]["size"]) for n in NAMES}
    uvs = evaluated_uvs(objects)
    missing = [n for n in NAMES if uvs[n] is None]
    if missing:
        raise RuntimeError("no evaluated 'lightmap' UV map on %s" % missing)
    blender_cov = {n: scenes.uv_coverage(uvs[n], sizes[n][0]) for n in NAMES}
    masks = {n: (blender_cov[n] > FULL) & (engine_cov[n] > FULL) for n in NAMES}

    if args.max_bounces is not None:
        scene.photonlm.max_bounces = args.max_bounces
    runs = []
    for i, target in enumerate(targets):
        last, rgb, err, cov = photonlm_bake(target, 11 + i, cap)
        st = dict(last["stats"])
        by_id = {last["objects"][n]["mesh_id"]: n for n in NAMES}
        st["error_worst_object"] = by_id.get(st.get("error_worst_mesh"))
        runs.append((target, last["wall_seconds"], st, rgb, err, cov, list(last["warnings"])))
        print("photonlm target %g: %.1f s (engine %.1f s), %.1f M photons, estimate %s, worst object %s %s"
              % (target, last["wall_seconds"], st["seconds_total"], st["photons_emitted"] / 1e6,
                 _pct(st["error_estimate"]), st["error_worst_object"], _pct(st.get("error_worst"))), flush=True)

    # Cycles bakes the evaluated meshes through the same maps, after the add-on has made them; the
    # preview off so that every material shows its own shading.
    scene.photonlm.preview_mode = 'OFF'
    islands = {n: int((blender_cov[n] > 0.0).sum()) for n in NAMES}
    a, b, ref_info = cycles_reference(objects, sizes, masks, islands, args.out, uvs, args.ref_samples, ref_seconds)
    ref = Reference(a, b, masks)
    print("reference noise (grey): %s scene-wide; %s" % (
        _pct(ref.noise_all), ", ".join("%s %s" % (n, _pct(ref.noise[n])) for n in NAMES)), flush=True)

    result = dict(machine=dict(cpus=os.cpu_count(), blender=bpy.app.version_string), library=lib_info,
                  sizes={n: list(sizes[n]) for n in NAMES}, warmup=warmup,
                  coverage_texels={n: dict(blender=int((blender_cov[n] > FULL).sum()),
                                           engine=int((engine_cov[n] > FULL).sum()), both=int(masks[n].sum()))
                                   for n in NAMES},
                  photon_cap=cap, max_bounces=int(scene.photonlm.max_bounces),
                  reference=dict(ref_info, noise=ref.noise_all, noise_objects=ref.noise,
                                 mean={n: float(ref.grey[n].mean()) for n in NAMES}),
                  targets=[])
    for target, wall, st, rgb, err, cov, warns in runs:
        per = {n: measure(ref, rgb, err, [n]) for n in NAMES}
        for n in NAMES:
            per[n]["estimate_covered"] = engine_estimate_covered(rgb[n], err[n], cov[n])
        whole = measure(ref, rgb, err, list(NAMES))
        for n in NAMES:
            per[n]["sq_share"] = per[n].pop("sq_error") / max(whole["sq_error"], 1e-300)
        worst = max(NAMES, key=lambda n: per[n]["measured"])
        engine = {k: st.get(k) for k in ("seconds_total", "seconds_export", "seconds_setup", "seconds_trace",
                                          "seconds_direct", "seconds_writeback", "photons_emitted", "direct_samples",
                                          "rays_traced", "error_estimate", "error_direct", "error_median",
                                          "error_p95", "error_above", "error_worst", "error_worst_object",
                                          "noisiest")}
        result["targets"].append(dict(target=target, seconds=wall, engine=engine, warnings=warns,
                                      scene=whole, objects=per, worst=worst))
        np.savez_compressed(os.path.join(args.out, "maps_%g.npz" % target),
                            **{"photonlm_" + n: rgb[n].astype(np.float32) for n in NAMES},
                            **{"error_" + n: err[n].astype(np.float32) for n in NAMES},
                            **{"mask_" + n: masks[n] for n in NAMES})
    result["seconds_total"] = time.perf_counter() - t_start
    bvc.write_results(args.out, "bench_artist_room", result, markdown(result))


if __name__ == "__main__":
    main()
