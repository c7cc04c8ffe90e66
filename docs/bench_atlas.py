"""Atlases against lightmaps of their own: what packing costs and what it saves. Runs in headless
Blender:

    PHOTONLM_LIBRARY=$PWD/build/lib/libphotonlm.so PHOTONLM_SOURCE_DIR=$PWD \
        blender -b --factory-startup --python docs/bench_atlas.py -- [--objects 200] [--page 2048]

Scene: a 20 x 20 m floor (density scale 0.25) and N cubes of five sizes (0.2 ... 1 m) in a grid under
a sun and a dim world, Texel Density 64, Margin 8, Max Photons 2 M, no target error, seed 1. It bakes
the scene once per layout (the same seed) and prints per layout: lightmap texels (baked, and in the
files: pages with margins and gaps), files written, the operator's wall time, the time of the
atlas step (packing, page copies, writing the page EXRs and heat maps, loading them, UV maps;
atlas.store), and the engine's RMS error estimate. Timings are wall-clock on a shared machine:
noisy.
"""
import math
import os
import sys
import tempfile
import time

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(HERE), "blend_tests"))
import scenes  # noqa: E402


def arg(name, default):
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    return type(default)(argv[argv.index(name) + 1]) if name in argv else default


def build(count):
    scenes.clear_scene()
    bpy.ops.mesh.primitive_plane_add(size=20.0)
    floor = bpy.context.active_object
    floor.name = "floor"
    floor.data.materials.append(scenes.diffuse_material("floor", (0.6, 0.6, 0.6)))
    floor.photonlm.density_scale = 0.25
    side = math.ceil(math.sqrt(count))
    for i in range(count):
        s = (0.2, 0.35, 0.5, 0.75, 1.0)[i % 5]
        bpy.ops.mesh.primitive_cube_add(size=s, location=(-9.0 + 18.0 * (i % side) / side,
                                                          -9.0 + 18.0 * (i // side) / side, s / 2))
        obj = bpy.context.active_object
        obj.name = "cube_%03d" % i
        obj.data.materials.append(scenes.diffuse_material("mat_%03d" % i, (0.5, 0.5, 0.5)))
    scenes.add_light("sun", 'SUN', (0, 0, 5), rotation=(0.5, 0.3, 0.0), energy=3.0)
    scenes.set_world_color((0.05, 0.05, 0.05))


def main():
    count, page = arg("--objects", 200), arg("--page", 2048)
    scenes.setup_paths()
    from photonlm_blender.writeback import atlas
    times = []
    store = atlas.store

    def timed(*args, **kwargs):
        t0 = time.perf_counter()
        out = store(*args, **kwargs)
        times.append(time.perf_counter() - t0)
        return out
    atlas.store = timed
    build(count)
    s = bpy.context.scene.photonlm
    s.texel_density = 64
    s.lightmap_margin = 8
    s.atlas_size = str(page)
    root = tempfile.mkdtemp(prefix="photonlm-bench-atlas-")
    print("objects %d + floor, page %d, margin 8, density 64" % (count, page))
    for layout in ('OBJECT', 'ATLAS'):
        s.lightmap_layout = layout
        s.output_dir = os.path.join(root, layout.lower())
        last = scenes.photonlm_bake(2_000_000, 8, seed=1, target_error=0.0)  # UV maps made here
        times.clear()
        last = scenes.photonlm_bake(2_000_000, 8, seed=1, target_error=0.0)  # timed with the maps reused
        baked = sum(o["size"][0] * o["size"][1] for o in last["objects"].values())
        files = [f for f in os.listdir(s.output_dir) if f.endswith("_lightmap.exr")]
        if layout == 'ATLAS':
            lay = bpy.context.scene[atlas.LAYOUT_KEY].to_dict()
            stored = len(lay["pages"]) * page * page
            pad = lay["pad"]
            cells = sum((b[3] + 2 * pad) * (b[4] + 2 * pad) for b in lay["blocks"].values())
            extra = "%d pages, cells fill %.0f %% of them" % (len(lay["pages"]), 100.0 * cells / stored)
        else:
            stored, extra = baked, "one per object"
        mb = sum(os.path.getsize(os.path.join(s.output_dir, f)) for f in files) / 1e6
        print("%-6s texels baked %9d  in files %9d  files %4d (%s, %.1f MB)  bake %.1f s  atlas step %s  "
              "error %.2f %%" % (layout, baked, stored, len(files), extra, mb, last["wall_seconds"],
                                 "%.2f s" % times[0] if times else "-",
                                 100.0 * float(last["stats"]["error_estimate"])))


main()
