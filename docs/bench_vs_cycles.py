"""Speed against error: photonlm against Cycles on three scenes, in headless Blender.

    PHOTONLM_LIBRARY=$PWD/build/lib/libphotonlm.so PHOTONLM_SOURCE_DIR=$PWD \
        blender -b --factory-startup --python docs/bench_vs_cycles.py -- --out /tmp/bench [--quick]
    /usr/bin/python3 docs/plot_vs_cycles.py /tmp/bench/bench_vs_cycles.json docs/images/speed_vs_cycles.png

Scenes (same objects, same fixed texel-aligned lightmap UVs for both bakers):
  cornell   blend_tests/scenes.py's Cornell box (area light, closed, full GI), 32 x 32 maps
  open      sun + uniform sky over an 8 m ground plane with three boxes (mostly direct light)
  interior  a closed 4 x 4 x 2.5 m room with a window hole; sun and sky outside (mostly indirect)
  open_sky  the open scene under a Nishita sky with its sun disc (not in the default --scenes)
  open_sphere  the open scene with a smooth-shaded sphere resting on the ground (not in the default)
  open_sphere_fine  the same with 4x the texels a side (256 x 256 maps, 0.03125 m texels; not in the default)

Reference: Cycles DIFFUSE bake, pass filter DIRECT + INDIRECT (no COLOR: irradiance / pi),
32 bounces, no clamping, box pixel filter, as two independent halves (seeds 1 and 2) averaged.
Their difference estimates the reference's own noise, which is removed in quadrature from every
measured error (E|x - ref|^2 = E|x - truth|^2 + E|ref - truth|^2 for independent noise).

Error: relative RMSE = sqrt(mean((x - ref)^2)) / mean(ref) over the fully covered texels of all
objects together, all three channels (also per object, and "grey": the same on the per-texel mean
of R, G, B, which is what photonlm's own estimate describes).

Times are operator wall times: bpy.ops.object.bake for Cycles (all objects in one call; seed 0,
independent of the reference's seeds), bpy.ops.photonlm.bake for photonlm (export + direct pass +
photons + EXR write-back + material wiring). One warm-up bake of each kind is run and discarded;
bakes under 2 s are timed --repeats times (default 3) and the median taken (their maps do not
change: fixed seeds).
"""
import argparse
import json
import math
import os
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(HERE)
sys.path.insert(0, os.path.join(SRC, "blend_tests"))
import scenes  # noqa: E402

ERROR_LEVELS = (0.05, 0.02, 0.01)


# ---- scenes --------------------------------------------------------------------------------------

def build_cornell():
    objs = scenes.cornell_box(resolution=32)
    return [objs[n] for n in scenes.CORNELL_OBJECTS], "area light 40 W, closed box, albedo 0.73 / red / green"


def _rect_quad(origin, u_axis, v_axis, u_len, v_len, uv0, texel, res):
    """A quad with corner `origin`, edges u_len * u_axis and v_len * v_axis (u x v = normal), and a
    texel-aligned lightmap rectangle starting at texel uv0 = (i, j) of a res x res map."""
    o = np.array(origin, float)
    u = np.array(u_axis, float) * u_len
    v = np.array(v_axis, float) * v_len
    nu, nv = round(u_len / texel), round(v_len / texel)
    i, j = uv0
    assert i + nu <= res and j + nv <= res, "layout does not fit"
    pts = [o, o + u, o + u + v, o + v]
    return tuple(tuple(p) for p in pts) + ((i / res, j / res, (i + nu) / res, (j + nv) / res),)


def build_open(density=1):
    """Sun (strength 4, 45 degrees up) and a uniform sky over an 8 x 8 m ground with three boxes.
    Uniform texel size 0.125 m / density: ground 64 x 64, boxes 64 x 64 maps (partly used), each
    x density."""
    T, R = 0.125 / density, 64 * density
    mat = scenes.diffuse_material
    objs = [scenes.plane("ground", mat("mat_ground", (0.35, 0.42, 0.30)), size=8.0, resolution=R)]
    boxes = [("box_a", (-1.5, -1.0), 0.5, 0.5, 1.0, 20, (0.8, 0.8, 0.8)),
             ("box_b", (1.25, 0.0), 0.75, 0.5, 0.75, -10, (0.7, 0.3, 0.2)),
             ("box_c", (-0.25, 1.75), 0.5, 0.5, 2.0, 45, (0.45, 0.5, 0.7))]
    for name, c, hx, hy, h, ang, alb in boxes:
        objs.append(scenes.quads_object(name, scenes.box_quads(c, hx, hy, h, math.radians(ang), T, R),
                                        mat("mat_" + name, alb), R))
    scenes.add_light("sun", 'SUN', (0, 0, 10), rotation=(math.radians(45), 0, math.radians(30)),
                     energy=4.0, angle=math.radians(1.0))
    scenes.set_world_color((0.30, 0.40, 0.60), 1.0)
    return objs, "sun 4 W/m^2 at 45 deg + sky (0.3, 0.4, 0.6), ground albedo ~0.36, three boxes"


def build_interior():
    """A closed room x, y in [-2, 2], z in [0, 2.5] (all faces inward), a 1.5 x 1 m window hole
    in the wall at y = -2, a 0.75 m box inside; sun (strength 4, 40 degrees up) through the
    window and a uniform sky outside. Texel 0.125 m, 32 x 32 maps."""
    T, R = 0.125, 32
    mat = scenes.diffuse_material
    white, floor_c = (0.8, 0.8, 0.8), (0.6, 0.45, 0.3)
    X, Y = (1, 0, 0), (0, 1, 0)
    Z = (0, 0, 1)
    nX, nY = (-1, 0, 0), (0, -1, 0)
    objs = []

    def obj(name, quads, alb):
        objs.append(scenes.quads_object(name, quads, mat("mat_" + name, alb), R))

    obj("floor", [_rect_quad((-2, -2, 0), X, Y, 4, 4, (0, 0), T, R)], floor_c)
    obj("ceiling", [_rect_quad((-2, -2, 2.5), Y, X, 4, 4, (0, 0), T, R)], white)
    obj("wall_north", [_rect_quad((-2, 2, 0), X, Z, 4, 2.5, (0, 0), T, R)], white)       # y = 2, faces -y
    obj("wall_west", [_rect_quad((-2, -2, 0), Y, Z, 4, 2.5, (0, 0), T, R)], white)       # x = -2, faces +x
    obj("wall_east", [_rect_quad((2, 2, 0), nY, Z, 4, 2.5, (0, 0), T, R)], (0.75, 0.8, 0.7))  # x = 2, -x
    # y = -2, faces +y: u along -x, v along +z; window x in [-0.75, 0.75], z in [0.75, 1.75]
    obj("wall_window", [
        _rect_quad((2, -2, 0), nX, Z, 4, 0.75, (0, 0), T, R),
        _rect_quad((2, -2, 1.75), nX, Z, 4, 0.75, (0, 14), T, R),
        _rect_quad((2, -2, 0.75), nX, Z, 1.25, 1.0, (0, 6), T, R),
        _rect_quad((-0.75, -2, 0.75), nX, Z, 1.25, 1.0, (22, 6), T, R),
    ], white)
    obj("box", scenes.box_quads((0.9, 0.9), 0.375, 0.375, 0.75, math.radians(15), T, R), (0.7, 0.7, 0.7))
    # Sun direction: local -Z rotated by 50 deg about x (into +y, 40 deg down), then 20 deg about z.
    scenes.add_light("sun", 'SUN', (0, -6, 6), rotation=(math.radians(50), 0, math.radians(20)),
                     energy=4.0, angle=math.radians(1.0))
    scenes.set_world_color((0.30, 0.40, 0.60), 1.0)
    # A portal in the window, as one sets up Cycles for interiors (both bakers sample the sky
    # through it; photonlm also sends the sun's photons through it). Local -Z points into the room.
    portal = scenes.add_light("window_portal", 'AREA', (0, -2, 1.25), rotation=(math.radians(90), 0, 0),
                              shape='RECTANGLE', size=1.5, size_y=1.0)
    portal.data.cycles.is_portal = True
    return objs, ("closed room, window 1.5 x 1 m with a portal, sun 4 W/m^2 + sky outside, white walls, "
                  "albedo 0.8")


def build_open_sky():
    """The open scene's ground and boxes under a Nishita sky with its sun disc (35 degrees up) instead
    of the sun lamp and the uniform sky: the add-on renders the sky into a map. Cycles samples it
    with a 2048 importance map (its default 1024 map misses part of a small sun)."""
    objs, _ = build_open()
    for o in [o for o in bpy.context.scene.objects if o.type == 'LIGHT']:
        bpy.data.objects.remove(o)
    world = bpy.context.scene.world
    nt = world.node_tree
    sky = nt.nodes.new('ShaderNodeTexSky')
    sky.sky_type = scenes.physical_sky_type()
    sky.sun_elevation = math.radians(35.0)
    sky.sun_rotation = math.radians(60.0)
    nt.links.new(sky.outputs['Color'], nt.nodes['Background'].inputs['Color'])
    nt.nodes['Background'].inputs['Strength'].default_value = 1.0
    world.cycles.sampling_method = 'MANUAL'
    world.cycles.sample_map_resolution = 2048
    return objs, "Nishita sky with its sun disc (35 deg up), ground albedo ~0.36, three boxes"


def build_open_sphere(density=1):
    """The open scene with a smooth-shaded UV sphere (radius 0.75 m, 48 x 24) resting on the ground:
    a curved object whose shading normals both bakers interpolate. Its lightmap UVs are the
    sphere's own latitude-longitude map (no overlaps), 64 x 64 (x density, as every map)."""
    objs, _ = build_open(density)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=48, ring_count=24, radius=0.75, location=(2.0, -2.0, 0.75))
    ball = bpy.context.active_object
    ball.name = "sphere"
    mesh = ball.data
    mesh.polygons.foreach_set("use_smooth", np.ones(len(mesh.polygons), bool))
    uv = np.empty(2 * len(mesh.loops), np.float32)
    mesh.uv_layers["UVMap"].data.foreach_get("uv", uv)
    mesh.uv_layers.new(name="lightmap").data.foreach_set("uv", uv)
    mesh.materials.append(scenes.diffuse_material("mat_sphere", (0.7, 0.7, 0.7)))
    ball.photonlm.resolution = 64 * density
    return objs + [ball], ("sun 4 W/m^2 at 45 deg + sky (0.3, 0.4, 0.6), ground albedo ~0.36, three boxes "
                           "and a smooth sphere (r 0.75 m, 48 x 24)" + (", %dx the texels a side" % density
                                                                         if density > 1 else ""))


SCENES = {"cornell": build_cornell, "open": build_open, "interior": build_interior, "open_sky": build_open_sky,
          "open_sphere": build_open_sphere, "open_sphere_fine": lambda: build_open_sphere(density=4)}


# ---- bakes ---------------------------------------------------------------------------------------

def cycles_bake(objects, samples, seed, supersample=1):
    """scenes.cycles_bake at each object's resolution: DIFFUSE DIRECT+INDIRECT, 32 bounces, no
    clamp, box filter, the given seed. Returns ({name: (h, w, 3)}, operator wall seconds)."""
    return scenes.cycles_bake(objects, None, ("DIRECT", "INDIRECT"), samples, bounces=32, seed=seed,
                              supersample=supersample)


_CAPTURED_ERRORS = {}


def _hook_bridge():
    """Record each lightmap's per-texel standard error (the EXR's error channel) as the add-on
    copies it out of the result: lets us compare the engine's estimate per object."""
    pl = scenes.setup_paths().bridge.get()
    if getattr(pl.Result.lightmap, "_bench_hook", False):
        return
    orig = pl.Result.lightmap

    def lightmap(self, mesh_id):
        lm = orig(self, mesh_id)
        _CAPTURED_ERRORS[mesh_id] = np.array(lm[1], np.float64)  # Lightmap(rgb, error, hits, coverage)
        return lm
    lightmap._bench_hook = True
    pl.Result.lightmap = lightmap


def photonlm_bake(out_dir, target_error=0.0, time_budget=0.0, photons=0, seed=1, direct_samples=64,
                  max_bounces=1024):
    from photonlm_blender.writeback import record
    _CAPTURED_ERRORS.clear()
    last = scenes.photonlm_bake(photons, max_bounces, seed=seed, target_error=target_error,
                                time_budget=time_budget, direct_samples=direct_samples, output_dir=out_dir)
    wall = last["wall_seconds"]
    stats = dict(last["stats"], **bpy.context.scene[record.STATS_KEY])
    maps, errs = {}, {}
    for name, o in last["objects"].items():
        maps[name] = np.array(o["rgb"], np.float64)
        errs[name] = _CAPTURED_ERRORS.get(o["mesh_id"])
    return maps, errs, wall, stats, list(last["warnings"])


# ---- metrics -------------------------------------------------------------------------------------

def edge_mask(ref, mask, noise, frac=0.25):
    """Texels at hard edges (shadow and contact boundaries): the reference's grey value varies by
    more than `frac` of the object's mean (plus 5 x the reference's per-texel noise `noise`)
    across the texel's covered 3 x 3 neighbourhood."""
    g = ref.mean(axis=2)
    h, w = g.shape
    big = np.full((h + 2, w + 2), np.nan)
    big[1:-1, 1:-1] = np.where(mask, g, np.nan)
    stack = np.stack([big[1 + dy:h + 1 + dy, 1 + dx:w + 1 + dx] for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
    with np.errstate(all="ignore"):
        rng = np.nanmax(stack, axis=0) - np.nanmin(stack, axis=0)
    return mask & (rng > frac * float(g[mask].mean()) + 5.0 * noise)


class Metric:
    """Relative RMSE against a reference over the fully covered texels, with the reference's own
    noise (estimated from its two independent halves) removed in quadrature."""

    def __init__(self, objects, half_a, half_b, edges=None):
        self.names = [o.name for o in objects]
        self.mask = {o.name: scenes.layout_coverage(o, o.photonlm.resolution) > 0.999 for o in objects}
        self.ref = {n: 0.5 * (half_a[n] + half_b[n]) for n in self.names}
        self.refv = {n: self.ref[n][self.mask[n]] for n in self.names}            # (k, 3)
        self.var = {n: ((half_a[n] - half_b[n]) ** 2 / 4.0)[self.mask[n]] for n in self.names}
        self.var_g = {n: ((half_a[n] - half_b[n]).mean(axis=2) ** 2 / 4.0)[self.mask[n]] for n in self.names}
        self.edges = edges or {n: edge_mask(self.ref[n], self.mask[n], math.sqrt(float(self.var_g[n].mean())))
                               for n in self.names}
        self.edge_sel = {n: self.edges[n][self.mask[n]] for n in self.names}      # (k,) bool
        self.texels = {n: int(self.mask[n].sum()) for n in self.names}
        self.mean_all = float(np.concatenate([self.refv[n] for n in self.names]).mean())
        self.ref_noise = self._noise(self.var)
        self.ref_noise_grey = self._noise(self.var_g)
        self.ref_noise_obj = {n: math.sqrt(float(self.var[n].mean())) / float(self.refv[n].mean())
                              for n in self.names}

    def _noise(self, var, sel=None):
        names = self.names
        v = np.concatenate([var[n] if sel is None else var[n][sel[n]] for n in names])
        return math.sqrt(float(v.mean())) / self.mean_all

    @staticmethod
    def _corr(raw, noise):
        return math.sqrt(max(raw * raw - noise * noise, 0.0))

    def _error(self, maps, names, sel=None, grey=False):
        """Reference-noise-corrected relative RMSE over `names` (texels where sel[n], default all),
        normalised by the mean of the reference over the same objects' covered texels."""
        sq, var, ref = [], [], []
        for n in names:
            k = slice(None) if sel is None else sel[n]
            d = maps[n][self.mask[n]] - self.refv[n]
            if grey:
                sq.append((d.mean(axis=1) ** 2)[k])
                var.append(self.var_g[n][k])
            else:
                sq.append((d ** 2)[k].ravel())
                var.append(self.var[n][k].ravel())
            ref.append(self.refv[n].ravel())
        sq, var = np.concatenate(sq), np.concatenate(var)
        if sq.size == 0:
            return None, None
        m = float(np.concatenate(ref).mean())
        raw = math.sqrt(float(sq.mean())) / m
        return raw, self._corr(raw, math.sqrt(float(var.mean())) / m)

    def __call__(self, maps, est_errors=None):
        per = {}
        smooth = {n: ~self.edge_sel[n] for n in self.names}
        for n in self.names:
            x = maps[n][self.mask[n]]
            raw, err = self._error(maps, [n])
            m = float(self.refv[n].mean())
            entry = dict(raw=raw, error=err, grey=self._error(maps, [n], grey=True)[1],
                         smooth=self._error(maps, [n], smooth)[1], mean_ratio=float(x.mean()) / m,
                         sq_share=float(((x - self.refv[n]) ** 2).sum()), edge_texels=int(self.edge_sel[n].sum()))
            if est_errors is not None and est_errors.get(n) is not None:
                e = est_errors[n][self.mask[n]]
                entry["estimate"] = math.sqrt(float((e ** 2).mean())) / float(x.mean(axis=1).mean())
            per[n] = entry
        tot = sum(p["sq_share"] for p in per.values())
        for p in per.values():
            p["sq_share"] /= max(tot, 1e-300)
        raw, err = self._error(maps, self.names)
        out = dict(raw=raw, error=err, grey=self._error(maps, self.names, grey=True)[1],
                   smooth=self._error(maps, self.names, smooth)[1],
                   edge_share=float(sum(((maps[n][self.mask[n]] - self.refv[n]) ** 2)[self.edge_sel[n]].sum()
                                        for n in self.names)) / max(tot, 1e-300),
                   objects=per)
        if est_errors is not None and all(est_errors.get(n) is not None for n in self.names):
            # The engine's estimate restricted to these texels (the error channel; mean-RGB based).
            e = np.concatenate([est_errors[n][self.mask[n]] ** 2 for n in self.names])
            v = np.concatenate([maps[n][self.mask[n]].mean(axis=1) for n in self.names])
            out["estimate_texels"] = math.sqrt(float(e.mean())) / float(v.mean())
        return out


def time_for_error(points, target):
    """Seconds a method needs for `target` error, by log-log interpolation along its curve of
    (seconds, error) points (lower envelope: best error reached by that time). Outside the
    measured range: extrapolated from the nearest point with error ~ t^-1/2, flagged."""
    pts = sorted((p for p in points if p[0] > 0 and p[1] > 0), key=lambda p: p[0])
    env, best = [], float("inf")
    for t, e in pts:
        if e < best:
            env.append((t, e))
            best = e
    if not env:
        return None, True
    if target >= env[0][1]:
        t, e = env[0]
        return (t * (e / target) ** 2, True) if target > env[0][1] * 1.0001 else (t, False)
    for (t0, e0), (t1, e1) in zip(env, env[1:]):
        if e1 <= target <= e0:
            if e0 == e1:
                return t0, False
            a = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(t0) + a * (math.log(t1) - math.log(t0))), False
    t, e = env[-1]
    if len(env) >= 2:
        (t0, e0) = env[-2]
        slope = (math.log(e) - math.log(e0)) / (math.log(t) - math.log(t0))
        if slope > -0.25:  # the error has stopped falling (bias): no extrapolation
            return None, True
    return t * (e / target) ** 2, True


# ---- driver --------------------------------------------------------------------------------------

def median_seconds(first, repeats, again, short=2.0):
    """The median time of `repeats` runs (the first took `first` s; again() runs once more and
    returns its seconds). Runs under `short` s are repeated: on a shared 2-core machine their
    times vary by 10-30 %; their results do not (fixed seeds)."""
    if repeats <= 1 or first >= short:
        return first
    times = [first] + [again() for _ in range(repeats - 1)]
    return float(np.median(times))


def run_scene(name, args, plan):
    print("\n=== scene %s ===" % name, flush=True)
    scenes.clear_scene()
    objects, description = SCENES[name]()
    bpy.context.view_layer.update()
    out_lm = os.path.join(args.out, "lightmaps", name)
    os.makedirs(out_lm, exist_ok=True)

    def reference(ss):
        """Two independent halves (seeds 1, 2), cached per scene, sample count and supersampling."""
        spp = max(1, plan["ref_samples"] // (2 * ss * ss))
        f = os.path.join(args.out, "ref_%s_%d_ss%d.npz" % (name, plan["ref_samples"], ss))
        if args.reuse_ref and os.path.exists(f):
            z = np.load(f)
            print("reference (x%d): reused %s" % (ss, f), flush=True)
            return ({o.name: z["a_" + o.name] for o in objects}, {o.name: z["b_" + o.name] for o in objects},
                    float(z["seconds"]))
        a, ta = cycles_bake(objects, spp, 1, supersample=ss)
        b, tb = cycles_bake(objects, spp, 2, supersample=ss)
        np.savez(f, seconds=ta + tb, **{"a_" + k: v for k, v in a.items()}, **{"b_" + k: v for k, v in b.items()})
        print("reference (x%d): Cycles 2 x %d samples at %dx%d texels per texel in %.1f s"
              % (ss, spp, ss, ss, ta + tb), flush=True)
        return a, b, ta + tb

    cycles_bake(objects, 1, 0)  # warm-up (kernel set-up), discarded
    half_a, half_b, ref_seconds = reference(1)
    metric = Metric(objects, half_a, half_b)
    print("reference noise (estimated): %.3f %% (grey %.3f %%); covered texels %d, at hard edges %d"
          % (100 * metric.ref_noise, 100 * metric.ref_noise_grey, sum(metric.texels.values()),
             sum(int(v.sum()) for v in metric.edge_sel.values())), flush=True)
    metric_ss, ss_seconds = None, None
    if args.supersample > 1:
        sa, sb, ss_seconds = reference(args.supersample)
        metric_ss = Metric(objects, sa, sb, edges=metric.edges)
        d = metric_ss({n: metric.ref[n] for n in metric.names})
        print("supersampled reference: noise %.3f %%; the plain reference differs from it by %.2f %% "
              "(%.2f %% away from hard edges)" % (100 * metric_ss.ref_noise, 100 * d["error"], 100 * d["smooth"]),
              flush=True)

    result = dict(description=description, objects=[dict(name=n, resolution=o.photonlm.resolution,
                                                         texels=metric.texels[n])
                                                    for n, o in zip(metric.names, objects)],
                  reference=dict(samples=plan["ref_samples"], seconds=ref_seconds, noise=metric.ref_noise,
                                 edge_texels=sum(int(v.sum()) for v in metric.edge_sel.values()),
                                 supersample=args.supersample, supersampled_seconds=ss_seconds,
                                 supersampled_noise=metric_ss.ref_noise if metric_ss else None,
                                 plain_vs_supersampled=metric_ss({n: metric.ref[n] for n in metric.names})
                                 if metric_ss else None,
                                 noise_grey=metric.ref_noise_grey, noise_objects=metric.ref_noise_obj,
                                 mean=metric.mean_all),
                  cycles=[], photonlm=[])

    def vs_ss(maps):
        if metric_ss is None:
            return None
        d = metric_ss(maps)
        return dict(error=d["error"], smooth=d["smooth"], raw=d["raw"])

    # With portals in the scene Cycles is also run without them (portal lights hidden from
    # render): the speed-up is taken against the faster of the two at each error.
    portals = [o for o in bpy.context.scene.objects
               if o.type == 'LIGHT' and getattr(o.data.cycles, "is_portal", False) and not o.hide_render]
    for variant in ("", " no portal") if portals else ("",):
        for o in portals:
            o.hide_render = bool(variant)
        for spp in plan["cycles_samples"]:
            maps, sec = cycles_bake(objects, spp, 0)
            sec = median_seconds(sec, args.repeats, lambda: cycles_bake(objects, spp, 0)[1])
            m = metric(maps)
            if not variant:
                maps_c = maps
            result["cycles"].append(dict(setting="%d spp%s" % (spp, variant), samples=spp, seconds=sec,
                                         series=variant.strip() or "default", texel_average=vs_ss(maps), **m))
            print("cycles%s %5d spp  %7.2f s  error %6.2f %% (raw %6.2f, away from edges %6.2f, vs texel-average "
                  "ref %s)" % (variant, spp, sec, 100 * m["error"], 100 * m["raw"], 100 * m["smooth"],
                               _pct(vs_ss(maps))), flush=True)
    for o in portals:
        o.hide_render = False

    photonlm_bake(out_lm, target_error=0.1, seed=999)  # warm-up (library load, first export)
    for i, (target, budget) in enumerate(plan["photonlm"]):
        maps, est, sec, st, warns = photonlm_bake(out_lm, target_error=target, time_budget=budget,
                                                   seed=11 + i)
        m = metric(maps, est)
        if target and not (budget and st["seconds_total"] > 0.5 * budget):  # a run the budget cut stands alone
            sec = median_seconds(sec, args.repeats, lambda: photonlm_bake(out_lm, target_error=target,
                                                                          time_budget=budget, seed=11 + i)[2])
        maps_p, est_p = maps, est
        setting = ("target %g" % target) if target else ("budget %g s" % budget)
        result["photonlm"].append(dict(
            setting=setting, target_error=target, time_budget=budget, seconds=sec,
            seconds_engine=st["seconds_total"], seconds_export=st["seconds_export"],
            seconds_setup=st["seconds_setup"], seconds_trace=st["seconds_trace"],
            seconds_direct=st["seconds_direct"],
            photons=st["photons_emitted"], direct_samples=st["direct_samples"], rays=st["rays_traced"],
            reported=st["error_estimate"], reported_direct=st.get("error_direct"), warnings=warns,
            texel_average=vs_ss(maps), **m))
        print("photonlm %-12s %7.2f s (engine %.2f = set-up %.3f + photons %.3f + direct %.3f + rest, export %.2f)"
              "  %d photons  error %6.2f %% (raw %6.2f, grey "
              "%6.2f, away from edges %6.2f, vs texel-average ref %s)  reported %6.2f %%  reported/measured %.2f"
              % (setting, sec, st["seconds_total"], st["seconds_setup"], st["seconds_trace"], st["seconds_direct"],
                 st["seconds_export"], st["photons_emitted"], 100 * m["error"],
                 100 * m["raw"], 100 * m["grey"], 100 * m["smooth"], _pct(vs_ss(maps)), 100 * st["error_estimate"],
                 st["error_estimate"] / max(m["error"], 1e-12)), flush=True)

    # The maps of the last (most accurate) run of each method, for closer looks.
    np.savez_compressed(os.path.join(args.out, "maps_%s.npz" % name),
                        **{"ref_" + n: metric.ref[n] for n in metric.names},
                        **{"mask_" + n: metric.mask[n] for n in metric.names},
                        **{"cycles_" + n: v for n, v in maps_c.items()},
                        **{"photonlm_" + n: v for n, v in maps_p.items()},
                        **{"photonlm_err_" + n: v for n, v in est_p.items() if v is not None})
    add_crossings(result)
    return result


def add_crossings(result):
    """Time each method needs for 5, 2 and 1 % error, and the speed-up, against each reference.
    Both bakers converge to texel-centre values (photonlm's default texel_value), so the plain
    reference is each one's own limit."""
    def crossings(err_c, err_p):
        cross = {}
        series = sorted({r.get("series", "default") for r in result["cycles"]})
        for lvl in ERROR_LEVELS:
            # The faster Cycles series (with or without portals) at this error.
            best = [time_for_error([(r["seconds"], err_c(r)) for r in result["cycles"]
                                    if r.get("series", "default") == s], lvl) for s in series]
            best = [b for b in best if b[0]]
            tc, xc = min(best) if best else (None, False)
            tp, xp = time_for_error([(r["seconds"], err_p(r)) for r in result["photonlm"]], lvl)
            cross["%g" % lvl] = dict(cycles=tc, cycles_extrapolated=xc, photonlm=tp, photonlm_extrapolated=xp,
                                     ratio=(tc / tp) if tc and tp else None)
        return cross

    def plain(r):
        return r["error"]

    def ta(r):
        return r["texel_average"]["error"]
    result["time_for_error"] = crossings(plain, plain)
    if all(r.get("texel_average") for r in result["cycles"] + result["photonlm"]):
        result["time_for_error_texel_average"] = crossings(ta, ta)
    result.pop("time_for_error_own_limit", None)


def _pct(d, key="error"):
    return "-" if not d or d.get(key) is None else "%.2f %%" % (100 * d[key])


def markdown(name, r):
    lines = ["### %s: %s" % (name, r["description"]), "",
             "Reference: Cycles %d samples (%.0f s), its own noise %.2f %% (removed in quadrature). "
             "%d covered texels in %d objects." % (r["reference"]["samples"], r["reference"]["seconds"] or 0,
                                                   100 * r["reference"]["noise"],
                                                   sum(o["texels"] for o in r["objects"]), len(r["objects"])),
             "",
             "Columns: error against that reference; the same away from hard edges (%d texels where the "
             "reference changes by > 25 %% of the object mean within 3 x 3 are left out); error against a "
             "texel-average reference (Cycles at %d x %d texels per texel, box-averaged)."
             % (r["reference"]["edge_texels"], r["reference"]["supersample"], r["reference"]["supersample"]),
             "",
             "| method | setting | seconds | error | away from edges | vs texel-average ref | reported error "
             "| reported / measured (plain, texel-average) | photons |",
             "|---|---|---|---|---|---|---|---|---|"]
    for c in r["cycles"]:
        lines.append("| Cycles | %s | %.2f | %.2f %% | %.2f %% | %s | | | |"
                     % (c["setting"], c["seconds"], 100 * c["error"], 100 * c["smooth"], _pct(c["texel_average"])))
    for p in r["photonlm"]:
        ta = p["texel_average"]["error"] if p.get("texel_average") else None
        lines.append("| photonlm | %s | %.2f | %.2f %% | %.2f %% | %s | %.2f %% | %.2f, %s | %.1f M |"
                     % (p["setting"], p["seconds"], 100 * p["error"], 100 * p["smooth"], _pct(p["texel_average"]),
                        100 * p["reported"], p["reported"] / max(p["error"], 1e-12),
                        "-" if ta is None else "%.2f" % (p["reported"] / max(ta, 1e-12)), p["photons"] / 1e6))

    def fmt(t, x):
        return "not reached" if t is None else ("%s%.2f" % ("~" if x else "", t))
    lines += ["", "Time to reach an error (log-log interpolation; ~ = extrapolated as t ~ error^-2 beyond the "
              "measured range; 'not reached' = the curve has flattened above it). References: plain = both "
              "against the Cycles reference (texel-centre values, what both converge to); texel average = both "
              "against the supersampled one:", "",
              "| error | reference | Cycles (s) | photonlm (s) | speed-up (Cycles / photonlm) |", "|---|---|---|---|---|"]
    for key, label in (("time_for_error", "plain"), ("time_for_error_texel_average", "texel average")):
        for lvl, c in r.get(key, {}).items():
            lines.append("| %g %% | %s | %s | %s | %s |"
                         % (100 * float(lvl), label, fmt(c["cycles"], c["cycles_extrapolated"]),
                            fmt(c["photonlm"], c["photonlm_extrapolated"]),
                            "-" if c["ratio"] is None else "%.2f" % c["ratio"]))
    # Per-object error of the most accurate photonlm run, next to Cycles' best.
    if r["photonlm"] and r["cycles"]:
        p = r["photonlm"][-1]
        c = [c for c in r["cycles"] if c.get("series", "default") == "default"][-1]
        lines += ["", "Per object: photonlm %s vs Cycles %s (share = fraction of the total squared error)."
                  % (p["setting"], c["setting"]), "",
                  "| object | texels | photonlm error | away from edges | photonlm estimate | share | mean ours/ref "
                  "| Cycles error | share |", "|---|---|---|---|---|---|---|---|---|"]
        for o in r["objects"]:
            n = o["name"]
            po, co = p["objects"][n], c["objects"][n]
            lines.append("| %s | %d | %.2f %% | %s | %s | %.0f %% | %.4f | %.2f %% | %.0f %% |"
                         % (n, o["texels"], 100 * po["error"], _pct(po, "smooth"), _pct(po, "estimate"),
                            100 * po["sq_share"], po["mean_ratio"], 100 * co["error"], 100 * co["sq_share"]))
    return "\n".join(lines)


def snapshot_library(out):
    """Bake with a private copy of the engine library, so that a rebuild during the run cannot
    change or break it; record which build it was."""
    import hashlib
    import shutil
    import subprocess
    src = os.environ.get("PHOTONLM_LIBRARY")
    info = {}
    if src and os.path.exists(src):
        dst = os.path.join(out, "libphotonlm.so")
        # The add-on's self-contained copy (what Blender 4.3 and 5.2 load) finds its libraries
        # beside it: they are copied along.
        folder = os.path.dirname(os.path.abspath(src))
        for name in os.listdir(folder):
            if ".so" in name and name != os.path.basename(src):
                shutil.copy2(os.path.join(folder, name), os.path.join(out, name))
        shutil.copy2(src, dst + ".tmp")
        os.replace(dst + ".tmp", dst)
        os.environ["PHOTONLM_LIBRARY"] = dst
        with open(dst, "rb") as f:
            info["sha256"] = hashlib.sha256(f.read()).hexdigest()[:16]
        info["built"] = time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime(os.path.getmtime(src)))
    try:
        info["git"] = subprocess.run(["git", "-C", SRC, "describe", "--always", "--dirty"], capture_output=True,
                                     text=True, timeout=10).stdout.strip()
    except Exception:  # noqa: BLE001
        pass
    return info


def write_json(path, results):
    """results to `path`, written to a temporary name and renamed (a run cut short leaves the last whole file)."""
    with open(path + ".tmp", "w") as f:
        json.dump(results, f, indent=1)
    os.replace(path + ".tmp", path)


def write_results(out, stem, results, md):
    """results as `stem`.json (write_json) and the tables `md` as `stem`.md into `out`; prints the
    tables and where the JSON went."""
    path = os.path.join(out, stem + ".json")
    write_json(path, results)
    with open(os.path.join(out, stem + ".md"), "w") as f:
        f.write(md + "\n")
    print("\n" + md)
    print("\nwrote %s (%.0f s in all)" % (path, results["seconds_total"]), flush=True)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="bench_vs_cycles.py")
    ap.add_argument("--out", default="/tmp/bench")
    ap.add_argument("--quick", action="store_true", help="small reference and fewer settings (development)")
    ap.add_argument("--scenes", default="cornell,open,interior")
    ap.add_argument("--ref-samples", type=int, default=0, help="override the reference sample count")
    ap.add_argument("--supersample", type=int, default=4,
                    help="also bake a texel-average reference at k x k texels per texel (1 = off)")
    ap.add_argument("--reuse-ref", action="store_true", help="reuse a cached reference from --out")
    ap.add_argument("--targets", help="photonlm's target errors, comma-separated (default 0.08,0.04,0.02,0.01,0.007; "
                    "--quick: 0.08,0.04,0.02), each with a 60 s time budget (20 s with --quick)")
    ap.add_argument("--repeats", type=int, default=3,
                    help="time each bake under 2 s this many times and take the median (results are the same)")
    ap.add_argument("--markdown-only", metavar="JSON", help="only rewrite the tables from an earlier run's JSON")
    args = ap.parse_args(argv)
    if args.markdown_only:
        with open(args.markdown_only) as f:
            results = json.load(f)
        for r in results["scenes"].values():
            add_crossings(r)
        with open(args.markdown_only, "w") as f:
            json.dump(results, f, indent=1)
        md = "\n\n".join(markdown(n, r) for n, r in results["scenes"].items())
        with open(os.path.join(os.path.dirname(os.path.abspath(args.markdown_only)), "bench_vs_cycles.md"), "w") as f:
            f.write(md + "\n")
        print(md)
        return
    os.makedirs(args.out, exist_ok=True)
    os.environ.setdefault("PHOTONLM_TEST_OUT", args.out)
    lib_info = snapshot_library(args.out)
    scenes.setup_paths()
    _hook_bridge()
    if args.quick:
        plan = dict(ref_samples=512, cycles_samples=(1, 4, 16, 64),
                    photonlm=[(0.08, 20.0), (0.04, 20.0), (0.02, 20.0)])
    else:
        plan = dict(ref_samples=4096, cycles_samples=(1, 4, 16, 64, 256, 1024),
                    photonlm=[(0.08, 60.0), (0.04, 60.0), (0.02, 60.0), (0.01, 60.0), (0.007, 60.0)])
    if args.ref_samples:
        plan["ref_samples"] = args.ref_samples
    if args.targets:
        plan["photonlm"] = [(float(t), 20.0 if args.quick else 60.0) for t in args.targets.split(",")]
    t0 = time.perf_counter()
    results = dict(machine=dict(cpus=os.cpu_count(), blender=bpy.app.version_string), library=lib_info,
                   quick=args.quick,
                   plan=dict(ref_samples=plan["ref_samples"], cycles_samples=list(plan["cycles_samples"]),
                             photonlm=[list(p) for p in plan["photonlm"]]),
                   scenes={})
    for name in args.scenes.split(","):
        results["scenes"][name] = run_scene(name, args, plan)
        write_json(os.path.join(args.out, "bench_vs_cycles.json"), results)
    results["seconds_total"] = time.perf_counter() - t0
    write_results(args.out, "bench_vs_cycles", results,
                  "\n\n".join(markdown(n, r) for n, r in results["scenes"].items()))


if __name__ == "__main__":
    main()
