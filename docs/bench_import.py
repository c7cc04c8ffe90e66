"""Importing a bake folder against baking in Blender: what the import costs, and that it changes nothing.

    PHOTONLM_LIBRARY=build/lib/libphotonlm.so blender -b --factory-startup --python-exit-code 1 \
        --python docs/bench_import.py -- [--res 512] [--photons 2000000] [--out /tmp/bench_import]

The Cornell box (seven objects of res x res texels) and a UV sphere (256 x 128 segments, 65 k
triangles, 2 res x 2 res texels, an automatic lightmap UV map). Exports it as a scene file, bakes the
file with `photonlm bake` (one process: the import reads a single bake's folder as it reads a merged
one), bakes the same scene in Blender (same seed and photons), then imports the folder (File >
Import > PhotonLM bake folder) and prints the in-Blender bake's write-back time against the
import's reading and write-back times (wall seconds), and the largest difference between the
imported and the in-Blender lightmaps (the error of the import against that reference).
"""
import os
import shutil
import subprocess
import sys
import time

import bpy
import numpy as np

SRC = os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(SRC, "blend_tests"))
import scenes  # noqa: E402


def args():
    import argparse
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser(prog="bench_import")
    p.add_argument("--res", type=int, default=512)
    p.add_argument("--photons", type=int, default=2_000_000)
    p.add_argument("--out", default="/tmp/bench_import")
    return p.parse_args(argv)


def main():
    a = args()
    scenes.setup_paths()
    import photonlm
    from photonlm_blender.writeback import record
    shutil.rmtree(a.out, ignore_errors=True)
    os.makedirs(a.out)
    scenes.clear_scene()
    scenes.cornell_box(resolution=a.res)
    bpy.ops.mesh.primitive_uv_sphere_add(segments=256, ring_count=128, radius=0.3, location=(0, -0.3, 1.0))
    ball = bpy.context.active_object
    ball.name = "ball"
    ball.photonlm.resolution = 2 * a.res
    ball.data.materials.append(scenes.diffuse_material("mat_ball", (0.5, 0.5, 0.5)))
    s = bpy.context.scene.photonlm
    s.photons, s.target_error, s.direct_samples, s.seed = a.photons, 0.0, 4, 5
    scene_json = os.path.join(a.out, "scene.json")
    bpy.ops.photonlm.export_scene_file(filepath=scene_json)
    lib = os.environ["PHOTONLM_LIBRARY"]
    cli = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(lib)), "..", "bin", "photonlm"))
    farm = os.path.join(a.out, "farm")
    t = time.perf_counter()
    subprocess.run([cli, "bake", scene_json, "-o", farm], check=True, capture_output=True)
    cli_seconds = time.perf_counter() - t
    s.output_dir = os.path.join(a.out, "blender")
    bpy.ops.photonlm.bake()
    ref = {n: np.array(o["rgb"] if o["rgb"] is not None else photonlm.read_lightmap_exr(o["path"]).rgb)
           for n, o in record.last()["objects"].items()}
    ref_writeback = float(bpy.context.scene[record.STATS_KEY]["seconds_writeback"])
    bpy.ops.photonlm.remove_preview()
    s.output_dir = os.path.join(a.out, "import")
    t = time.perf_counter()
    bpy.ops.photonlm.import_bake_folder(directory=farm)
    wall = time.perf_counter() - t
    st = bpy.context.scene[record.STATS_KEY]
    worst = max(float(np.max(np.abs(photonlm.read_lightmap_exr(o["path"]).rgb - ref[n])))
                for n, o in record.last()["objects"].items())
    texels = sum(o["size"][0] * o["size"][1] for o in record.last()["objects"].values())
    print("bench_import: %d objects, %.2f M texels, %s photons; photonlm bake %.1f s" % (
        len(ref), texels / 1e6, "{:,}".format(a.photons), cli_seconds))
    print("bench_import: in-Blender write-back %.2f s | import %.2f s: reading %.2f s, write-back %.2f s | "
          "max |import - in-Blender| %.3g" % (ref_writeback, wall, st["seconds_import"], st["seconds_writeback"], worst))


main()
