"""Orientation lightmaps: OL-resolved lightmaps against ordinary lightmaps, and OL set-up cost.

    PHOTONLM_LIBRARY=$PWD/build/lib/libphotonlm.so PYTHONPATH=python_bridge:python_bridge/tests \
        /usr/bin/python3 docs/bench_ol.py [--quick] [--out docs/images/ol_torus.png]

1. A torus (R = 1, r = 0.35, tilted 35 degrees about x: non-convex, shadows itself), 96 x 48
   segments, a 128 x 64 lightmap over its (phi, psi) parameters, on a grey 8 x 8 m floor, lit by a
   sun (tilted 40 degrees from the zenith, as in bench_csg.py) and a uniform sky. Reference: an
   ordinary lightmap bake (8 M photons, 256 direct samples). Then the torus in an OL group
   (8, 16, 32 bins per side; 1 M and 4 M photons): its lightmap comes back resolved from the OL.
   Error = relative RMSE over covered texels (mean RGB) against the reference, and mean ratio.
   "normal-binned reference" = the reference lightmap averaged (area-weighted) over all texels
   whose normal falls into the same bin of the equal-area octahedral map: the best any OL of that
   resolution can do without bin interpolation (no photon noise), i.e. the error due to
   self-shadowing and bin size alone.
2. The same for a UV sphere (r = 1) on the floor (convex, but the floor hides the lower half's sky
   and the sphere shadows the floor it sees).
3. OL set-up cost: a "tree crown" of N small random triangles in one OL group (no lightmaps),
   200 k photons, each N in its own process (peak memory = ru_maxrss of that process).
4. The N = 120,000-leaf crown of part 3 (same seed) on the floor, sun + sky, baked three ways,
   each in its own process: A = the crown with an ordinary lightmap (every leaf its own 3 x 3 texel
   cell of a 1041 x 1041 atlas, half-texel margins); B = the crown in a 16 x 16 OL group, no
   lightmap; C = both (the atlas resolved from the OL). Reference: A with as many photons as fit in
   ~60 s (--ref-seconds), 64 direct samples, plus a second seed for its noise. Leaf value =
   coverage-weighted mean over the leaf's cell (B: the OL bin at the leaf's normal); errors =
   relative RMSE over leaves and the ratio of the area-weighted crown flux. About 3 minutes.
Timings are wall-clock on a shared 2-core machine: noisy.
"""
import argparse
import json
import resource
import subprocess
import sys
import time

import numpy as np

import photonlm

TILT = 35.0
R_MAJOR, R_MINOR = 1.0, 0.35
SKY = (0.3, 0.35, 0.45)


def rot_x(deg):
    s, c = np.sin(np.radians(deg)), np.cos(np.radians(deg))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def param_mesh(f, nu, nv):
    """A (u, v) grid surface: f(u, v) -> points (arrays, u, v in [0, 1]); per-corner UVs = (u, v).
    Returns positions (V, 3), triangles (T, 3), uv (T, 3, 2). Degenerate triangles are dropped."""
    us, vs = np.meshgrid(np.arange(nu + 1) / nu, np.arange(nv + 1) / nv, indexing="ij")
    pos = f(us.ravel(), vs.ravel())
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    tri = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    uvall = np.stack([us.ravel(), vs.ravel()], 1)
    p = pos[tri]
    area2 = np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    keep = area2 > 1e-12
    tri = tri[keep]
    return pos.astype(np.float32), tri.astype(np.uint32), uvall[tri].astype(np.float32)


def torus_geometry(seg=96, rings=48):
    rot = rot_x(TILT)
    lift = R_MAJOR * np.sin(np.radians(TILT)) + R_MINOR + 0.05  # lowest point 5 cm above the floor

    def f(u, v):
        phi, psi = 2 * np.pi * u, 2 * np.pi * v
        p = np.stack([(R_MAJOR + R_MINOR * np.cos(psi)) * np.cos(phi),
                      (R_MAJOR + R_MINOR * np.cos(psi)) * np.sin(phi), R_MINOR * np.sin(psi)], 1)
        return p @ rot.T + (0, 0, lift)

    def normal(u, v):
        phi, psi = 2 * np.pi * u, 2 * np.pi * v
        n = np.stack([np.cos(psi) * np.cos(phi), np.cos(psi) * np.sin(phi), np.sin(psi)], -1)
        return n @ rot.T

    # |dP/dphi x dP/dpsi| = r (R + r cos psi): texel area weight
    def weight(u, v):
        return R_MINOR * (R_MAJOR + R_MINOR * np.cos(2 * np.pi * v)) + 0 * u
    return param_mesh(f, seg, rings), normal, weight


def sphere_geometry(seg=96, rings=48):
    c = np.array([0, 0, 1.05])

    def dirs(u, v):
        phi, th = 2 * np.pi * u, np.pi * (1 - v)  # v = 0 at the south pole
        return np.stack([np.sin(th) * np.cos(phi), np.sin(th) * np.sin(phi), np.cos(th)], -1)

    def weight(u, v):
        return np.sin(np.pi * (1 - v)) + 0 * u
    return param_mesh(lambda u, v: dirs(u, v) + c, seg, rings), dirs, weight


def check_winding(pos, tri, normal_fn, uv):
    """Fraction of triangles whose winding normal points along the analytic outward normal."""
    p = pos[tri].astype(np.float64)
    gn = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    cuv = uv.mean(axis=1)
    return float(np.mean(np.sum(gn * normal_fn(cuv[:, 0], cuv[:, 1]), 1) > 0))


def build(kind, ol_res):
    scene = photonlm.Scene()
    obj_mat = scene.add_material(albedo=(0.7, 0.7, 0.7))  # material 0
    grey = scene.add_material(albedo=(0.5, 0.5, 0.5))
    (pos, tri, uv), _, _ = torus_geometry() if kind == "torus" else sphere_geometry()
    res = (128, 64)
    mesh = scene.add_mesh(kind, pos, tri, uv, material_ids=np.full(len(tri), obj_mat, np.uint32),
                          resolution=res)
    if ol_res:
        scene.set_mesh_ol_group(mesh, scene.add_ol_group(kind, resolution=ol_res))
    h = 4.0
    quad = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], np.float32)
    scene.add_mesh("floor", quad, np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
                   material_ids=np.array([grey, grey], np.uint32))
    sun = np.eye(4, dtype=np.float32)
    sun[:3, :3] = rot_x(40.0)
    scene.add_light("SUN", power=3.0, matrix=sun)
    scene.set_world(SKY)
    return scene, mesh


def bake(kind, ol_res, photons, direct, seed):
    t0 = time.perf_counter()
    scene, mesh = build(kind, ol_res)
    with scene.bake(photons=photons, direct_samples=direct, seed=seed) as r:
        lm = r.lightmap(mesh)
        st = r.stats
        ols = r.ol_stats(0) if ol_res else None
        warn = r.warnings
    scene.close()
    return dict(lm=lm, stats=st, ol=ols, wall=time.perf_counter() - t0, warnings=warn)


def oct_encode(d):
    """numpy port of native/src/ol/octahedral.h oct_encode: unit directions (..., 3) -> u, v."""
    ax, ay, az = np.abs(d[..., 0]), np.abs(d[..., 1]), np.abs(d[..., 2])
    r = np.sqrt((ax * ax + ay * ay) / (1 + az))
    phi = np.arctan2(ay, ax) * (2 / np.pi)
    b = phi * r
    a = r - b
    low = d[..., 2] < 0
    a, b = np.where(low, 1 - b, a), np.where(low, 1 - a, b)
    return 0.5 * (np.copysign(a, d[..., 0]) + 1), 0.5 * (np.copysign(b, d[..., 1]) + 1)


def normal_binned(ref, normal_fn, weight_fn, n):
    """Reference lightmap replaced by its area-weighted mean over texels in the same normal bin."""
    h, w = ref.shape
    v, u = np.meshgrid((np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w, indexing="ij")
    nn = normal_fn(u, v)
    nn /= np.linalg.norm(nn, axis=-1, keepdims=True)
    eu, ev = oct_encode(nn)
    b = np.minimum((ev * n).astype(int), n - 1) * n + np.minimum((eu * n).astype(int), n - 1)
    wt = weight_fn(u, v)
    s = np.bincount(b.ravel(), (wt * ref).ravel(), n * n)
    a = np.bincount(b.ravel(), wt.ravel(), n * n)
    return (s / np.maximum(a, 1e-30))[b]


def compare(x, ref, mask, wt=None):
    """Relative RMSE over covered texels, ratio of texel means, and (with wt = texel areas) the
    ratio of area-weighted means (= ratio of the reflected flux)."""
    d = x[mask] - ref[mask]
    out = (float(np.sqrt(np.mean(d * d)) / ref[mask].mean()), float(x[mask].mean() / ref[mask].mean()))
    if wt is None:
        return out
    return out + (float(np.sum(wt[mask] * x[mask]) / np.sum(wt[mask] * ref[mask])),)


def texel_weights(shape, weight_fn):
    h, w = shape
    v, u = np.meshgrid((np.arange(h) + 0.5) / h, (np.arange(w) + 0.5) / w, indexing="ij")
    return weight_fn(u, v)


def object_study(kind, ref_photons, ol_photons, resolutions, quick):
    geo, normal_fn, weight_fn = torus_geometry() if kind == "torus" else sphere_geometry()
    wind = check_winding(geo[0], geo[1], normal_fn, geo[2])
    ref = bake(kind, 0, ref_photons, 256 if not quick else 64, 99)
    refm = ref["lm"].rgb.mean(axis=2)
    mask = ref["lm"].coverage > 0.5
    rows, maps = [], {"ref": refm}
    wt = texel_weights(refm.shape, weight_fn)
    print("\n### %s: %d triangles, %d covered texels, outward winding %.3f" % (
        kind, len(geo[1]), mask.sum(), wind))
    print("reference: ordinary lightmap, %.1f M photons, %d direct samples: %.1f s engine "
          "(%.1f s wall), reported error %.2f %%" % (ref_photons / 1e6, 256 if not quick else 64,
                                                     ref["stats"]["seconds_total"], ref["wall"],
                                                     100 * ref["stats"]["error_estimate"]))
    for w in ref["warnings"]:
        print("  warning:", w)
    ref2 = bake(kind, 0, ref_photons, 256 if not quick else 64, 98)
    e2, r2, f2 = compare(ref2["lm"].rgb.mean(axis=2), refm, mask, wt)
    print("reference noise: a second reference (seed 98) differs by %.2f %% (mean ratio %.4f, "
          "flux ratio %.4f), i.e. ~%.2f %% per reference" % (100 * e2, r2, f2, 100 * e2 / np.sqrt(2)))
    print()
    print("| %s in OL group | photons | engine s | wall s | error vs reference | mean ratio (texels) | "
          "flux ratio (area-weighted) | normal-binned reference error | OL hits | orphan flux |" % kind)
    print("|---|---|---|---|---|---|---|---|---|---|")
    for n in resolutions:
        nb = normal_binned(refm, normal_fn, weight_fn, n)
        e_nb, r_nb, f_nb = compare(nb, refm, mask, wt)
        for p in ol_photons:
            b = bake(kind, n, p, 64, 1)
            m = b["lm"].rgb.mean(axis=2)
            e, ratio, fratio = compare(m, refm, mask, wt)
            bad = int(np.sum(~np.isfinite(b["lm"].rgb)))
            rows.append(dict(res=n, photons=p, seconds=b["stats"]["seconds_total"], err=e, ratio=ratio,
                             e_nb=e_nb, hits=b["ol"]["hits"]))
            print("| %d x %d bins | %g M | %.2f | %.2f | %.1f %% | %.4f | %.4f | %.1f %% | %d | %.3g |%s" % (
                n, n, p / 1e6, b["stats"]["seconds_total"], b["wall"], 100 * e, ratio, fratio, 100 * e_nb,
                b["ol"]["hits"], b["ol"]["orphan_flux"], " %d non-finite values!" % bad if bad else ""),
                flush=True)
            if n == 16 and p == ol_photons[1]:
                maps["ol16"] = m
                maps["nb16"] = nb
            for wmsg in b["warnings"]:
                print("  warning:", wmsg)
    # seed spread of the flux ratio (is a low ratio a bias or noise?)
    spread = [compare(bake(kind, 16, ol_photons[1], 64, sd)["lm"].rgb.mean(axis=2), refm, mask, wt)
              for sd in range(1, 6)]
    e, _, f = np.array(spread).T
    print("\n16 x 16 bins, %g M photons, seeds 1-5: error %.1f-%.1f %%, flux ratio %.4f-%.4f (mean %.4f)" % (
        ol_photons[1] / 1e6, 100 * e.min(), 100 * e.max(), f.min(), f.max(), f.mean()))
    return rows, maps, mask


def tree_one(n, photons, use_ol):
    """One tree of n random leaves in an OL group (or, use_ol False, as plain geometry) on a floor
    with a 32 x 32 lightmap (own process: its peak memory). n = 0: import only (baseline memory)."""
    if n == 0:
        return dict(peak_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
    rng = np.random.default_rng(12345)
    # leaf centres uniform in an ellipsoid crown (radii 1.5, 1.5, 1.2) centred 3 m up
    c = rng.normal(size=(n, 3))
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    c *= rng.random((n, 1)) ** (1 / 3)
    c = c * (1.5, 1.5, 1.2) + (0, 0, 3.0)
    size = 0.06  # leaf corners within 6 cm of the centre
    pos = (c[:, None, :] + rng.uniform(-size, size, (n, 3, 3))).reshape(-1, 3).astype(np.float32)
    tri = np.arange(3 * n, dtype=np.uint32).reshape(n, 3)
    p = pos.astype(np.float64)[tri]
    exact = float(np.sum(0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)))
    t0 = time.perf_counter()
    scene = photonlm.Scene()
    scene.add_material(albedo=(0.4, 0.6, 0.3))
    grey = scene.add_material(albedo=0.5)
    leaves = scene.add_mesh("leaves", pos, tri)
    if use_ol:
        g = scene.add_ol_group("crown", resolution=16)
        scene.set_mesh_ol_group(leaves, g)
    h = 4.0
    quad = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], np.float32)
    uv = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)
    scene.add_mesh("floor", quad, np.array([[0, 1, 2], [0, 2, 3]], np.uint32), uv,
                   material_ids=np.array([grey, grey], np.uint32), resolution=32)
    sun = np.eye(4, dtype=np.float32)
    sun[:3, :3] = rot_x(40.0)
    scene.add_light("SUN", power=3.0, matrix=sun)
    scene.set_world(SKY)
    with scene.bake(photons=photons, seed=1, direct_samples=16) as r:
        st = r.stats
        if not use_ol:
            scene.close()
            return dict(n=n, seconds_setup=st["seconds_setup"], seconds_total=st["seconds_total"],
                        wall=time.perf_counter() - t0,
                        peak_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
        ols, ol = r.ol_stats(g), r.orientation_lightmap(g)
    scene.close()
    return dict(n=n, exact_area=exact, seconds_setup=st["seconds_setup"], seconds_total=st["seconds_total"],
                wall=time.perf_counter() - t0, peak_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                hits=ols["hits"], area=ols["area"], bins_area=float(ol.area.astype(np.float64).sum()),
                flux=ols["flux"], orphan=ols["orphan_flux"], covered_bins=int((ol.area > 0).sum()),
                nonfinite=int((~np.isfinite(ol.rgb)).sum()), mean_value=float(ol.rgb.mean()))


# ---- part 4: the 120 k-leaf tree baked with an OL against ordinary lightmaps ----------------------

def leaves_geometry(n):
    """The crown of tree_one (same seed, same leaves): positions (3n, 3) float32, triangles, areas
    (double) and unit geometric normals (by winding, the side lightmaps and OLs record)."""
    rng = np.random.default_rng(12345)
    c = rng.normal(size=(n, 3))
    c /= np.linalg.norm(c, axis=1, keepdims=True)
    c *= rng.random((n, 1)) ** (1 / 3)
    c = c * (1.5, 1.5, 1.2) + (0, 0, 3.0)
    size = 0.06
    pos = (c[:, None, :] + rng.uniform(-size, size, (n, 3, 3))).reshape(-1, 3).astype(np.float32)
    tri = np.arange(3 * n, dtype=np.uint32).reshape(n, 3)
    p = pos.astype(np.float64)[tri]
    g = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    ln = np.linalg.norm(g, axis=1)
    return pos, tri, 0.5 * ln, g / ln[:, None]


def atlas_uv(n, c):
    """Every leaf its own c x c texel cell (leaf i: column i % side, row i // side) of a square
    atlas of side * c texels; the triangle is the cell's lower-left half inset by half a texel."""
    side = int(np.ceil(np.sqrt(n)))
    i = np.arange(n)
    x0, y0 = (i % side) * c, (i // side) * c
    corners = np.array([[0.5, 0.5], [c - 0.5, 0.5], [0.5, c - 0.5]])
    uv = (np.stack([x0, y0], 1)[:, None, :] + corners[None]) / (side * c)
    return uv.astype(np.float32), side


def leaf_values(lm, n, side, c):
    """Per-leaf value: coverage-weighted mean (RGB mean) over its cell's covered texels, and the
    leaf's standard error from the texels' errors (texel errors taken as independent)."""
    w = side * c
    val = lm.rgb.mean(axis=2)[:w, :w].reshape(side, c, side, c)
    cov = lm.coverage[:w, :w].reshape(side, c, side, c)
    err = lm.error[:w, :w].reshape(side, c, side, c)
    cov = np.where(cov > 0, cov, 0)
    s = (val * cov).sum(axis=(1, 3)).ravel()[:n]
    a = (cov).sum(axis=(1, 3)).ravel()[:n]
    e2 = ((err * cov) ** 2).sum(axis=(1, 3)).ravel()[:n]
    return s / np.maximum(a, 1e-30), np.sqrt(e2) / np.maximum(a, 1e-30), a


def tree_variant(variant, n, photons, direct, seed, c, out_npy):
    """One bake of the crown (own process): A = atlas lightmap, B = OL group without lightmap,
    C = atlas lightmap resolved from the OL group. Leaf values go to out_npy."""
    pos, tri, area, nrm = leaves_geometry(n)
    t0 = time.perf_counter()
    scene = photonlm.Scene()
    scene.add_material(albedo=(0.4, 0.6, 0.3))
    grey = scene.add_material(albedo=0.5)
    side = int(np.ceil(np.sqrt(n)))
    if variant in "AC":
        uv, side = atlas_uv(n, c)
        leaves = scene.add_mesh("leaves", pos, tri, uv, resolution=side * c)
    else:
        leaves = scene.add_mesh("leaves", pos, tri)
    if variant in "BC":
        g = scene.add_ol_group("crown", resolution=16)
        scene.set_mesh_ol_group(leaves, g)
    h = 4.0
    quad = np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], np.float32)
    scene.add_mesh("floor", quad, np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
                   material_ids=np.array([grey, grey], np.uint32))
    sun = np.eye(4, dtype=np.float32)
    sun[:3, :3] = rot_x(40.0)
    scene.add_light("SUN", power=3.0, matrix=sun)
    scene.set_world(SKY)
    t_build = time.perf_counter() - t0
    with scene.bake(photons=photons, seed=seed, direct_samples=direct) as r:
        st = r.stats
        warn = r.warnings
        out = dict(variant=variant, photons=photons, direct=direct, seconds_setup=st["seconds_setup"],
                   seconds_total=st["seconds_total"], seconds_direct=st["seconds_direct"],
                   error_estimate=st["error_estimate"], build_wall=t_build, warnings=warn[:5])
        if variant in "AC":
            lm = r.lightmap(leaves)
            vals, errs, cov = leaf_values(lm, n, side, c)
            out["texels"] = int(lm.coverage.size)
            out["covered_texels"] = int((lm.coverage > 0).sum())
            out["nonfinite"] = int((~np.isfinite(lm.rgb)).sum())
            del lm
        if variant in "BC":
            ol = r.orientation_lightmap(g)
            ols = r.ol_stats(g)
            out.update(hits=ols["hits"], orphan=ols["orphan_flux"])
            nb = ol.resolution
            eu, ev = oct_encode(nrm)
            b = np.minimum((ev * nb).astype(int), nb - 1) * nb + np.minimum((eu * nb).astype(int), nb - 1)
            binned = ol.rgb.mean(axis=2).ravel()[b]
            if variant == "B":
                vals, errs, cov = binned, ol.error.ravel()[b], np.ones(n)
            else:
                out["c_vs_bin_lookup"] = float(np.sqrt(np.mean((vals - binned) ** 2)) / binned.mean())
    out["wall"] = time.perf_counter() - t0
    scene.close()
    out["peak_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    out["leaves_uncovered"] = int(np.sum(cov <= 0))
    np.save(out_npy, np.stack([vals, errs]))
    return out


def tree_study(quick, ref_seconds):
    """Part 4: the 120 k-leaf crown, atlas lightmap (A), OL without lightmap (B), both (C)."""
    n = 12_000 if quick else 120_000
    c = 3
    tmp = "/tmp/bench_ol_tree_%d" % __import__("os").getpid()
    __import__("os").makedirs(tmp, exist_ok=True)

    def sub(variant, photons, direct, seed):
        f = "%s/%s_%d_%d_%d.npy" % (tmp, variant, photons, direct, seed)
        out = subprocess.run([sys.executable, __file__, "--tree-variant", variant, str(n), str(photons),
                              str(direct), str(seed), str(c), f], check=True, capture_output=True,
                             text=True).stdout
        r = json.loads(out.strip().splitlines()[-1])
        v = np.load(f)
        return r, v[0], v[1]

    _, _, area, _ = leaves_geometry(n)
    # reference photon count: time a small atlas bake, scale to ~ref_seconds
    p0 = 200_000 if quick else 2_000_000
    probe, _, _ = sub("A", p0, 64, 7)
    per_photon = max(probe["seconds_total"] - probe["seconds_direct"] - probe["seconds_setup"], 1e-3) / p0
    fixed = probe["seconds_direct"] + probe["seconds_setup"]
    ref_p = int(max(p0, (ref_seconds - fixed) / per_photon) // 1_000_000 * 1_000_000 or p0)
    ref, refv, refe = sub("A", ref_p, 64, 99)
    ref2, ref2v, _ = sub("A", ref_p, 64, 98)
    print("\n### tree crown: %d leaves, atlas %d x %d texels (%d x %d per leaf), 16 x 16 OL" % (
        n, ref["texels"] ** 0.5, ref["texels"] ** 0.5, c, c))
    ref_flux = np.sum(area * refv)
    rel_noise = np.sqrt(np.mean((ref2v - refv) ** 2) / 2) / refv.mean()
    print("second reference flux ratio %.4f" % (np.sum(area * ref2v) / ref_flux))
    print("reference: variant A, %.0f M photons, 64 direct samples: %.1f s engine (%.1f s direct), "
          "peak %.0f MB; its own per-leaf noise (seed 99 vs 98, / sqrt 2) %.2f %% rel. RMS; "
          "%d covered texels; %d leaves without a covered texel%s" % (
              ref_p / 1e6, ref["seconds_total"], ref["seconds_direct"], ref["peak_mb"], 100 * rel_noise,
              ref["covered_texels"], ref["leaves_uncovered"],
              "; warnings: " + " | ".join(ref["warnings"]) if ref["warnings"] else ""))
    base = subprocess.run([sys.executable, __file__, "--tree", "0", "0", "0"], check=True,
                          capture_output=True, text=True).stdout
    print("baseline peak (imports only): %.0f MB" % json.loads(base.strip().splitlines()[-1])["peak_mb"])
    print()
    print("| variant | photons | direct samples | seconds_setup | seconds_total | wall s (process) | peak MB | "
          "leaf rel. RMSE vs reference | crown flux ratio | notes |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    ok = np.isfinite(refv)
    for variant, photons, direct in (("A", 1_000_000, 16), ("A", 4_000_000, 16), ("B", 1_000_000, 0),
                                     ("B", 4_000_000, 0), ("B", 32_000_000, 0), ("C", 4_000_000, 16)):
        if quick:
            photons //= 10
        r, v, e = sub(variant, photons, direct, 1)
        d = v[ok] - refv[ok]
        rmse = np.sqrt(np.mean(d * d)) / refv[ok].mean()
        fr = np.sum(area * v) / ref_flux
        notes = []
        if "hits" in r:
            notes.append("%d OL hits, orphan %.3g" % (r["hits"], r["orphan"]))
        if "c_vs_bin_lookup" in r:
            notes.append("resolved map vs bin lookup %.1f %%" % (100 * r["c_vs_bin_lookup"]))
        if r.get("nonfinite"):
            notes.append("%d non-finite!" % r["nonfinite"])
        notes += r["warnings"]
        print("| %s | %g M | %d | %.3f | %.2f | %.1f | %.0f | %.1f %% | %.4f | %s |" % (
            variant, photons / 1e6, direct, r["seconds_setup"], r["seconds_total"], r["wall"], r["peak_mb"],
            100 * rmse, fr, "; ".join(notes)), flush=True)
    # what the best 16 x 16 OL could do: reference leaf values averaged (area-weighted) per normal bin
    _, _, _, nrm = leaves_geometry(n)
    eu, ev = oct_encode(nrm)
    b = np.minimum((ev * 16).astype(int), 15) * 16 + np.minimum((eu * 16).astype(int), 15)
    nbv = (np.bincount(b, area * refv, 256) / np.maximum(np.bincount(b, area, 256), 1e-30))[b]
    print("\nnormal-binned reference (reference leaf values averaged per 16 x 16 bin): %.1f %% leaf rel. "
          "RMSE, flux ratio %.4f" % (100 * np.sqrt(np.mean((nbv - refv) ** 2)) / refv.mean(),
                                     np.sum(area * nbv) / ref_flux))
    # self-shadowing: the reference by depth in the crown (normalised ellipsoid radius)
    pos = leaves_geometry(n)[0].reshape(n, 3, 3).mean(axis=1)
    rr = np.linalg.norm((pos - (0, 0, 3.0)) / (1.5, 1.5, 1.2), axis=1)
    print("reference leaf value (mean) by depth: " + ", ".join(
        "r %.1f-%.1f: %.4f (normal-binned %.4f)" % (lo, hi, refv[(rr >= lo) & (rr < hi)].mean(),
                                                    nbv[(rr >= lo) & (rr < hi)].mean())
        for lo, hi in ((0, 0.5), (0.5, 0.8), (0.8, 0.9), (0.9, 1.1))))


def save_image(maps, mask, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ref, ol = maps["ref"], maps["ol16"]
    scale = np.percentile(ref[mask], 99)

    def tone(x):
        return np.clip(x / scale, 0, 1) ** (1 / 2.2)
    diff = np.where(mask, (ol - ref) / ref[mask].mean(), 0)
    lim = max(np.percentile(np.abs(diff), 99), 1e-6)
    fig, ax = plt.subplots(3, 1, figsize=(7, 10))
    ax[0].imshow(tone(ref), origin="lower", cmap="gray", vmin=0, vmax=1)
    ax[0].set_title("torus lightmap, reference (ordinary lightmap, 8 M photons)")
    ax[1].imshow(tone(ol), origin="lower", cmap="gray", vmin=0, vmax=1)
    ax[1].set_title("torus lightmap resolved from a 16 x 16 OL (4 M photons)")
    im = ax[2].imshow(diff, origin="lower", cmap="RdBu_r", vmin=-lim, vmax=lim)
    ax[2].set_title("(OL - reference) / mean(reference)")
    fig.colorbar(im, ax=ax[2], orientation="horizontal", fraction=0.05)
    for a in ax:
        a.set_xlabel("u = phi / 2 pi (around the ring)")
        a.set_ylabel("v = psi / 2 pi (around the tube)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    print("\nimage:", path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="small photon counts (smoke test)")
    ap.add_argument("--out", default="docs/images/ol_torus.png")
    ap.add_argument("--parts", default="1234")
    ap.add_argument("--tree", nargs=3, metavar=("N", "PHOTONS", "OL"))
    ap.add_argument("--tree-variant", nargs=7, metavar=("V", "N", "PHOTONS", "DIRECT", "SEED", "C", "NPY"))
    ap.add_argument("--ref-seconds", type=float, default=60.0)
    args = ap.parse_args()
    if args.tree_variant:
        v, *a, f = args.tree_variant
        print(json.dumps(tree_variant(v, *map(int, a), f)))
        return
    if args.tree:
        print(json.dumps(tree_one(int(args.tree[0]), int(args.tree[1]), args.tree[2] == "1")))
        return
    q = args.quick
    print("photonlm", photonlm.version(), "library", photonlm.library_path() if callable(
        getattr(photonlm, "library_path", None)) else "")
    ref_p = 500_000 if q else 8_000_000
    ol_p = (100_000, 400_000, 1_600_000) if q else (1_000_000, 4_000_000, 32_000_000)
    if "1" in args.parts:
        rows, maps, mask = object_study("torus", ref_p, ol_p, (8, 16, 32), q)
        if args.out and "ol16" in maps:
            save_image(maps, mask, args.out)
    if "2" in args.parts:
        object_study("sphere", ref_p, ol_p, (8, 16, 32), q)
    if "3" in args.parts:
        def sub(*a):
            out = subprocess.run([sys.executable, __file__, "--tree", *map(str, a)], check=True,
                                 capture_output=True, text=True).stdout
            return json.loads(out.strip().splitlines()[-1])
        base = sub(0, 0, 0)["peak_mb"]
        print("\nbaseline peak memory (python + numpy + photonlm imported, no scene): %.0f MB" % base)
        print("\n| leaves N | triangle area m^2 (exact) | OL area rel. diff | bins' area rel. diff | "
              "seconds_setup | seconds_total | peak MB | same leaves without OL: setup / total s, peak MB "
              "| OL hits | covered bins | orphan flux |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for n in (1000, 10_000, 120_000):
            r = sub(n, 200_000, 1)
            p = sub(n, 200_000, 0)
            print("| %d | %.6f | %.2e | %.2e | %.3f | %.3f | %.0f | %.3f / %.3f, %.0f | %d | %d | %.3g |%s" % (
                n, r["exact_area"], r["area"] / r["exact_area"] - 1, r["bins_area"] / r["exact_area"] - 1,
                r["seconds_setup"], r["seconds_total"], r["peak_mb"], p["seconds_setup"], p["seconds_total"],
                p["peak_mb"], r["hits"], r["covered_bins"], r["orphan"],
                " %d non-finite!" % r["nonfinite"] if r["nonfinite"] else ""), flush=True)
    if "4" in args.parts:
        tree_study(q, 5.0 if q else args.ref_seconds)

if __name__ == "__main__":
    main()
