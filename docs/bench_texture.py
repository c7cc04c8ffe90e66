"""The cost of albedo textures: the same furnace box baked with a plain albedo and with an albedo
texture of the same constant colour (so both have the analytic answer E / (1 - c) per channel).

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so PYTHONPATH=python_bridge \
        /usr/bin/python3 docs/bench_texture.py [--photons 4000000] [--size 1024]

Prints, per variant, the set-up time (texture loading: decode to linear float RGB in memory),
the photon pass time, photons per second and the RMS texel error relative to the exact value,
all channels. The texture is size x size pixels (8-bit, read as linear).
"""
import argparse
import os
import tempfile
import time

import numpy as np

import photonlm

C = np.array([102, 153, 51]) / 255.0  # 0.4, 0.6, 0.2
EMISSION = 0.25


def box_faces():
    """Six inward-facing unit quads of the cube [-0.5, 0.5]^3 (corners counter-clockwise from inside)."""
    faces = []
    for axis in range(3):
        for side in (-0.5, 0.5):
            b, c = (axis + 1) % 3, (axis + 2) % 3
            quad = np.zeros((4, 3), np.float32)
            quad[:, axis] = side
            for k, (pb, pc) in enumerate([(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)]):
                quad[k, b], quad[k, c] = pb, pc
            n = np.cross(quad[1] - quad[0], quad[3] - quad[0])
            if np.dot(n, -quad[0]) < 0:
                quad = quad[[0, 3, 2, 1]]
            faces.append(quad)
    return faces


TRIS = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
UV = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)


def bake(texture, photons, threads):
    with photonlm.Scene() as scene:
        mat = scene.add_material(albedo=(1.0, 1.0, 1.0) if texture else tuple(C), emission=EMISSION)
        if texture:
            scene.set_material_texture(mat, "albedo", texture, "linear")
        meshes = []
        for i, quad in enumerate(box_faces()):
            m = scene.add_mesh("face%d" % i, quad, TRIS, UV, resolution=16)
            if texture:
                scene.set_mesh_texture_uv(m, UV * 4.0)  # the image repeats 4 x 4 times per face
            meshes.append(m)
        t0 = time.perf_counter()
        with scene.bake(photons=photons, seed=1, threads=threads) as result:
            wall = time.perf_counter() - t0
            rgb = np.concatenate([result.lightmap(m).rgb.reshape(-1, 3) for m in meshes])
            st = result.stats
    truth = EMISSION / (1.0 - C)
    err = float(np.sqrt(np.mean(((rgb - truth) / truth) ** 2)))
    return wall, st, err


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--photons", type=int, default=4_000_000)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--threads", type=int, default=0)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "flat.ppm")
        with open(path, "wb") as f:
            f.write(b"P6\n%d %d\n255\n" % (args.size, args.size))
            f.write(np.tile(np.array([102, 153, 51], np.uint8), (args.size, args.size, 1)).tobytes())
        print("furnace box, 6 x 16 x 16 texels, %d photons, exact answer E / (1 - c), c = %s"
              % (args.photons, tuple(np.round(C, 3))))
        print("%-22s %9s %9s %9s %12s %10s" % ("variant", "wall s", "setup s", "trace s", "photons/s", "rms err"))
        for label, tex in (("plain albedo", None), ("texture %dx%d" % (args.size, args.size), path),
                           ("plain albedo (again)", None), ("texture (again)", path)):
            wall, st, err = bake(tex, args.photons, args.threads)
            print("%-22s %9.2f %9.3f %9.2f %12.3g %9.2f%%" % (label, wall, st["seconds_setup"], st["seconds_trace"],
                                                             st["photons_emitted"] / st["seconds_trace"], 100 * err))


if __name__ == "__main__":
    main()
