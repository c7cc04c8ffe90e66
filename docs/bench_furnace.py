"""Speed against error on scenes with analytic answers (closed furnace box).

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so PYTHONPATH=python_bridge \
        /usr/bin/python3 docs/bench_furnace.py [--plot docs/images/furnace_error.png]

Inside a closed box whose faces all emit radiance E and reflect albedo rho, every
texel's exact value is E / (1 - rho). For each rho and photon count this prints
the bake time and the texel error (RMS over texels, relative to the exact value),
and the error the engine itself reported (mean of the error channel).
"""
import argparse
import time

import numpy as np

import photonlm


def furnace_scene(rho, res=16):
    """Unit cube, six inward faces in a 3 x 2 atlas, each face res x res texels."""
    scene = photonlm.Scene()
    scene.add_material(albedo=(rho,) * 3, emission=(1.0,) * 3, name="furnace")
    pos, tris, uvs = [], [], []
    cells = [(0, 0), (1, 0), (2, 0), (0, 1), (1, 1), (2, 1)]
    for f, (axis, side) in enumerate([(a, s) for a in range(3) for s in (0.0, 1.0)]):
        b, c = (axis + 1) % 3, (axis + 2) % 3
        quad = np.zeros((4, 3), np.float32)
        quad[:, axis] = side
        for k, (pb, pc) in enumerate([(0, 0), (1, 0), (1, 1), (0, 1)]):
            quad[k, b], quad[k, c] = pb, pc
        n = np.cross(quad[1] - quad[0], quad[3] - quad[0])
        order = [0, 1, 2, 3] if np.dot(n, 0.5 - quad[0]) > 0 else [0, 3, 2, 1]
        quad = quad[order]
        base = len(pos) * 4
        pos.append(quad)
        tris += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
        cu, cv = cells[f]
        m = 1.0 / res  # one-texel margin inside each cell
        u0, u1 = (cu + m) / 3, (cu + 1 - m) / 3
        v0, v1 = (cv + m) / 2, (cv + 1 - m) / 2
        corner_uv = np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]], np.float32)
        uvs += [corner_uv[[0, 1, 2]], corner_uv[[0, 2, 3]]]
    mesh = scene.add_mesh("furnace", np.concatenate(pos), np.array(tris), np.array(uvs), None, (3 * res, 2 * res))
    return scene, mesh


def measure(rho, photons, seed=0):
    scene, mesh = furnace_scene(rho)
    t0 = time.perf_counter()
    # The raw photon estimator: photons carry direct light too, no pooling.
    with scene.bake(photons=photons, seed=seed, direct_samples=0, filter_radius=0) as result:
        seconds = time.perf_counter() - t0
        lm = result.lightmap(mesh)
        stats = result.stats
    scene.close()
    full = lm.coverage > 0.999
    exact = 1.0 / (1.0 - rho)
    value = lm.rgb.mean(axis=2)[full]
    rmse = float(np.sqrt(np.mean((value - exact) ** 2)) / exact)
    reported = float(np.mean(lm.error[full]) / exact)
    mean_err = float(abs(value.mean() - exact) / exact)
    return seconds, rmse, reported, mean_err, stats["rays_traced"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--plot", default=None)
    args = ap.parse_args()
    counts = [125_000, 500_000, 2_000_000, 8_000_000]
    rows = {}
    print("| albedo | photons | time (s) | Mrays/s | texel RMSE | reported error | error of the mean |")
    print("|---|---|---|---|---|---|---|")
    for rho in (0.5, 0.9, 0.99):
        rows[rho] = []
        for n in counts:
            s, rmse, rep, mean_err, rays = measure(rho, n)
            rows[rho].append((s, rmse))
            print("| %.2f | %d | %.3f | %.2f | %.2f%% | %.2f%% | %.3f%% |"
                  % (rho, n, s, rays / s * 1e-6, 100 * rmse, 100 * rep, 100 * mean_err))
    if args.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6, 4))
        for rho, pts in rows.items():
            t, e = zip(*pts)
            ax.loglog(t, [100 * x for x in e], "o-", label="albedo %.2f" % rho)
        t0, e0 = rows[0.5][0]
        ts = np.array([t0, rows[0.5][-1][0]])
        ax.loglog(ts, 100 * e0 * np.sqrt(t0 / ts), "k--", lw=0.8, label="1/sqrt(time)")
        ax.set_xlabel("bake time (s), 2 cores")
        ax.set_ylabel("texel RMS error (%)")
        ax.set_title("Furnace box: error against time")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.plot, dpi=110)
        print("plot:", args.plot)


if __name__ == "__main__":
    main()
