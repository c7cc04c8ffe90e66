"""Build a scene in numpy and bake it with the photonlm bridge: a room corner (floor and two walls)
with a sphere lit by a sun and a sky, written as EXR lightmaps.

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so PYTHONPATH=python_bridge \
        /usr/bin/python3 python_bridge/examples/bake_numpy_scene.py OUT_DIR [--target-error 0.03]

Prints the error the engine reached and each lightmap's mean value; returns the means (for tests).
"""
import argparse
import os

import numpy as np

import photonlm


def quad(origin, u, v):
    """A quad's four corners (counter-clockwise seen from the front), triangles and UVs filling [0, 1]^2."""
    o, u, v = (np.asarray(x, np.float32) for x in (origin, u, v))
    pos = np.array([o, o + u, o + u + v, o + v], np.float32)
    tris = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    uv = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)
    return pos, tris, uv


def uv_sphere(centre, radius, segments=48, rings=24):
    """A sphere as triangles; each triangle gets its own UV cell in a segments x rings atlas."""
    th = np.linspace(0, np.pi, rings + 1)
    ph = np.linspace(0, 2 * np.pi, segments + 1)
    grid = np.stack(np.meshgrid(ph, th), axis=-1)  # (rings+1, segments+1, 2)
    pts = np.stack([np.sin(grid[..., 1]) * np.cos(grid[..., 0]), np.sin(grid[..., 1]) * np.sin(grid[..., 0]),
                    -np.cos(grid[..., 1])], axis=-1) * radius + np.asarray(centre)
    pos = pts.reshape(-1, 3).astype(np.float32)
    tris, uvs = [], []
    w = segments + 1
    for j in range(rings):
        for i in range(segments):
            a, b, c, d = j * w + i, j * w + i + 1, (j + 1) * w + i + 1, (j + 1) * w + i
            u0, u1, v0, v1 = i / segments, (i + 1) / segments, j / rings, (j + 1) / rings
            tris += [[a, b, c], [a, c, d]]
            uvs += [[[u0, v0], [u1, v0], [u1, v1]], [[u0, v0], [u1, v1], [u0, v1]]]
    return pos, np.array(tris, np.uint32), np.array(uvs, np.float32)


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--target-error", type=float, default=0.03)
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    with photonlm.Scene() as scene:
        white = scene.add_material(albedo=0.8, name="white")
        red = scene.add_material(albedo=(0.7, 0.1, 0.1), name="red")
        meshes = {}
        for name, (o, u, v), mat in (("floor", ((-2, -2, 0), (4, 0, 0), (0, 4, 0)), white),
                                     ("wall_x", ((-2, 2, 0), (0, -4, 0), (0, 0, 3)), red),
                                     ("wall_y", ((-2, 2, 0), (0, 0, 3), (4, 0, 0)), white)):
            pos, tris, uv = quad(o, u, v)
            meshes[name] = scene.add_mesh(name, pos, tris, uv, material_ids=np.full(2, mat, np.uint32),
                                          resolution=64)
        pos, tris, uv = uv_sphere((0.3, 0.2, 0.6), 0.6)
        meshes["ball"] = scene.add_mesh("ball", pos, tris, uv, material_ids=np.full(len(tris), white, np.uint32),
                                        resolution=128)
        sun = np.eye(4)
        c, s = np.cos(np.radians(35)), np.sin(np.radians(35))
        sun[:3, :3] = [[1, 0, 0], [0, c, -s], [0, s, c]]
        scene.add_light("SUN", power=3.0, matrix=sun)
        scene.set_world((0.2, 0.25, 0.35))
        with scene.bake(photons=0, target_error=args.target_error, seed=1) as result:
            print("error %.2f %% (target %.2f %%), %d photons, %.2f s" % (
                100 * result.stats["error_estimate"], 100 * args.target_error, result.stats["photons_emitted"],
                result.stats["seconds_total"]))
            means = {}
            for name, mid in meshes.items():
                result.write_exr(mid, os.path.join(args.out, name + "_lightmap.exr"))
                lm = result.lightmap(mid)
                means[name] = float((lm.rgb.mean(axis=2) * lm.coverage).sum() / lm.coverage.sum())
                print("%-7s mean %.4f" % (name, means[name]))
    return means


if __name__ == "__main__":
    main()
