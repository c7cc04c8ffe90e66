"""Ten times the courtyard: a generated level of about 1,500 objects, 20 M triangles and 5 M texels,
lit by a sun, a physical sky and 50 lamps, baked through the add-on in headless Blender, with the
time of every stage and the peak memory (the courtyard benchmark's measurements, bench_courtyard.py).

    PHOTONLM_LIBRARY=$PWD/build/lib/libphotonlm.so PHOTONLM_SOURCE_DIR=$PWD \
        blender -b --factory-startup --python docs/bench_level.py -- --out /tmp/bench_level \
        [--scale 1] [--target 0.05] [--photons N] [--time-budget S] [--bakes 1] [--scene-file]
        [--profile] [--export-only] [--save]
    ... --python docs/bench_level.py -- --out DIR --scaling ONE.json TWO.json FULL.json

The level (--scale 1; --scale f multiplies every count by f), on a ground of 10 x 10 tiles of 8 m:
- 100 ground tiles, 128 x 128 lightmaps (flat);
- 60 buildings, one on each of 60 tiles: boxes of their own with a Bevel modifier, 128 x 128;
- 50 canopies: planes with Solidify and Bevel, a point lamp of 300 W under each (the 50 lamps), 64 x 64;
- 40 walls: a block with Array (6) and Mirror, 64 x 64;
- 340 crates: linked duplicates of one cube, each with a Bevel modifier, 32 x 32 (flat);
- 560 monkeys: linked duplicates of one Suzanne subdivided twice (15,744 triangles), smooth, 32 x 32
  (the add-on's Auto gives each an orientation lightmap: more than 4 triangles a texel);
- 300 rocks: displaced icospheres of their own, smooth: 250 of 20,480 triangles (orientation
  lightmaps by Auto), 50 with a live Subdivision Surface (viewport 1, render 2) on 320, refined by
  the engine; 64 x 64;
- 50 pillars: linked duplicates of one cylinder with Bevel and Subdivision Surface, smooth, 32 x 32;
- 50 trees: collection instances of one tree (a trunk and a crown of 81,920 triangles), geometry only.
Props stand clear of the buildings; rocks, crates and monkeys may lean into each other. Materials:
24 shared ones, half Principled BSDF, half Diffuse. A sun (strength 3, 40 degrees up) and a physical
sky. The add-on's defaults otherwise (Native Subdivision, Max Photons 50 M).

Printed and written to DIR/level.json, per bake: what bench_courtyard.py prints (objects, triangles,
texels, every stage's seconds and CPU seconds, peak memory of the Blender process, the engine's
estimate, the error reached) and the export's and write-back's share of the bake. --save writes the
level to DIR/level.blend (the lightmap UV maps made by the first bake included).

--scaling: no bake; the serial fraction of each stage (export, set-up, direct, photons and gather,
write-back) from a bake with a fixed photon count (--target 0 --photons N) run on one core
(`taskset -c 0 blender ...`) and on two, and with it the full level's stages at 2, 16 and 64 cores
(Amdahl's law per stage), into DIR/scaling.json.
"""
import argparse
import json
import math
import os
import random
import sys
import time

import bpy
import mathutils
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(HERE)
sys.path.insert(0, os.path.join(SRC, "blend_tests"))
sys.path.insert(0, HERE)
import scenes  # noqa: E402
import bench_courtyard  # noqa: E402

TILE = 8.0  # metres per ground tile
COUNTS = dict(tiles=100, buildings=60, canopies=50, walls=40, crates=340, monkeys=560, rocks=300, pillars=50,
              trees=50)


def _grid_mesh(name, size, cuts):
    """A square of side `size` in z = 0, cuts x cuts quads, facing up."""
    mesh = bpy.data.meshes.new(name)
    xs = np.linspace(-size / 2.0, size / 2.0, cuts + 1)
    verts = [(x, y, 0.0) for y in xs for x in xs]
    n = cuts + 1
    faces = [(r * n + c, r * n + c + 1, (r + 1) * n + c + 1, (r + 1) * n + c) for r in range(cuts) for c in range(cuts)]
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    return mesh


def _primitive(op, **kw):
    """The mesh of a primitive operator, its object removed."""
    op(**kw)
    obj = bpy.context.active_object
    mesh = obj.data
    bpy.data.objects.remove(obj)
    return mesh


def _smooth(mesh):
    mesh.polygons.foreach_set("use_smooth", [True] * len(mesh.polygons))
    mesh.update()


def _subsurf(obj, render=2, viewport=1):
    mod = obj.modifiers.new("Subdivision", 'SUBSURF')
    mod.levels = viewport
    mod.render_levels = render
    return mod


def _applied_subsurf(mesh, levels):
    """mesh with a Subdivision Surface of `levels` applied (a new mesh; mesh is removed)."""
    obj = bpy.data.objects.new("_subdivide", mesh)
    bpy.context.scene.collection.objects.link(obj)
    mod = obj.modifiers.new("Subdivision", 'SUBSURF')
    mod.levels = levels
    dg = bpy.context.evaluated_depsgraph_get()
    out = bpy.data.meshes.new_from_object(obj.evaluated_get(dg), depsgraph=dg)
    bpy.data.objects.remove(obj)
    bpy.data.meshes.remove(mesh)
    return out


def build(scale=1.0, seed=11):
    """The level. Returns (baked objects, counts)."""
    scenes.clear_scene()
    rng = random.Random(seed)
    counts = {k: max(1, int(round(v * scale))) for k, v in COUNTS.items()}
    side = max(1, int(round(math.sqrt(counts["tiles"]))))
    counts["tiles"] = side * side
    half = side * TILE / 2.0
    mats = [scenes.diffuse_material("Level%02d" % i, (rng.uniform(0.25, 0.8), rng.uniform(0.25, 0.8),
                                                      rng.uniform(0.25, 0.8)), principled=i % 2 == 0)
            for i in range(24)]
    coll = bpy.context.scene.collection
    objs = []

    def place(name, mesh, location, resolution, rotation=(0.0, 0.0, 0.0), lightmap=True):
        obj = bpy.data.objects.new(name, mesh)
        obj.location = location
        obj.rotation_euler = rotation
        if not mesh.materials:
            mesh.materials.append(rng.choice(mats))
        obj.photonlm.enabled = lightmap
        obj.photonlm.resolution = resolution
        coll.objects.link(obj)
        if lightmap:
            objs.append(obj)
        return obj

    plots = rng.sample(range(counts["tiles"]), min(counts["buildings"], counts["tiles"]))
    footprints = []  # (x, y, radius) of the buildings: nothing else stands in them

    def spot(margin=1.0, radius=0.8):
        for _ in range(200):
            x, y = rng.uniform(-half + margin, half - margin), rng.uniform(-half + margin, half - margin)
            if all((x - bx) ** 2 + (y - by) ** 2 > (r + radius) ** 2 for bx, by, r in footprints):
                return x, y
        return x, y

    for i in range(counts["tiles"]):
        r, c = divmod(i, side)
        place("Tile%03d" % i, _grid_mesh("Tile%03d" % i, TILE, 8),
              ((c + 0.5) * TILE - half, (r + 0.5) * TILE - half, 0.0), 128)
    for i, plot in enumerate(plots):  # one a ground tile, within it
        w, d, h = rng.uniform(3.5, 5.5), rng.uniform(3.5, 5.5), rng.uniform(4, 14)
        r, c = divmod(plot, side)
        x, y = (c + 0.5) * TILE - half, (r + 0.5) * TILE - half
        footprints.append((x, y, math.hypot(w, d) / 2.0))
        obj = place("Building%02d" % i, bench_courtyard.box_mesh("Building%02d" % i, (w, d, h)), (x, y, h / 2.0), 128,
                    rotation=(0.0, 0.0, rng.uniform(0, math.pi)))
        bevel = obj.modifiers.new("Bevel", 'BEVEL')
        bevel.width = 0.08
        bevel.segments = 2
    for i in range(counts["canopies"]):
        x, y = spot(2.0, 2.2)
        z = rng.uniform(2.6, 3.4)
        obj = place("Canopy%02d" % i, _grid_mesh("Canopy%02d" % i, 3.0, 2), (x, y, z), 64,
                    rotation=(0.0, 0.0, rng.uniform(0, math.pi)))
        solid = obj.modifiers.new("Solidify", 'SOLIDIFY')
        solid.thickness = 0.12
        bevel = obj.modifiers.new("Bevel", 'BEVEL')
        bevel.width = 0.03
        scenes.add_light("Lamp%02d" % i, 'POINT', (x, y, z - 0.5), energy=300.0,
                         color=(1.0, rng.uniform(0.7, 0.9), rng.uniform(0.5, 0.7)), shadow_soft_size=0.1)
    block = bench_courtyard.box_mesh("WallBlock", (1.0, 0.3, 2.0))
    for i in range(counts["walls"]):
        x, y = spot(6.0, 3.5)
        obj = place("Wall%02d" % i, block.copy(), (x, y, 1.0), 64, rotation=(0.0, 0.0, rng.uniform(0, math.pi)))
        array = obj.modifiers.new("Array", 'ARRAY')
        array.count = 6
        array.relative_offset_displace = (1.05, 0.0, 0.0)
        mirror = obj.modifiers.new("Mirror", 'MIRROR')
        mirror.use_axis = (False, True, False)
        mirror.use_bisect_axis = (False, False, False)
        mirror.mirror_offset_v = 0.0
        mirror.use_mirror_merge = False
        obj.data.transform(mathutils.Matrix.Translation((0.0, 0.6, 0.0)))  # two rows, mirrored in y
    bpy.data.meshes.remove(block)
    crate = bench_courtyard.box_mesh("Crate", (0.8, 0.8, 0.8))
    for i in range(counts["crates"]):
        x, y = spot()
        obj = place("Crate%03d" % i, crate, (x, y, 0.4), 32, rotation=(0.0, 0.0, rng.uniform(0, math.pi)))
        bevel = obj.modifiers.new("Bevel", 'BEVEL')
        bevel.width = 0.04
        bevel.segments = 3
    monkey = _applied_subsurf(_primitive(bpy.ops.mesh.primitive_monkey_add, size=1.2), 2)
    monkey.name = "Monkey"
    _smooth(monkey)
    for i in range(counts["monkeys"]):
        x, y = spot()
        place("Monkey%03d" % i, monkey, (x, y, 0.5), 32, rotation=(math.radians(-20.0), 0.0, rng.uniform(0, 2 * math.pi)))
    live_rocks = max(1, counts["rocks"] // 6)
    for i in range(counts["rocks"]):
        live = i < live_rocks
        mesh = _primitive(bpy.ops.mesh.primitive_ico_sphere_add, subdivisions=3 if live else 6, radius=1.0)
        mesh.name = "Rock%03d" % i
        co = np.empty(len(mesh.vertices) * 3, np.float32)
        mesh.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3)
        bumps = np.array([rng.uniform(-1, 1) for _ in range(9)], np.float32).reshape(3, 3)
        co *= (1.0 + 0.12 * np.sin(co @ bumps * 3.0).sum(axis=1, keepdims=True)) * np.array(
            [rng.uniform(0.6, 1.4), rng.uniform(0.6, 1.4), rng.uniform(0.4, 0.9)], np.float32)
        mesh.vertices.foreach_set("co", co.ravel())
        _smooth(mesh)
        x, y = spot(radius=1.5)
        footprints.append((x, y, 0.5))  # rocks lean on each other, none wholly inside another
        obj = place("Rock%03d" % i, mesh, (x, y, 0.2), 64, rotation=(0.0, 0.0, rng.uniform(0, math.pi)))
        if live:
            _subsurf(obj)
    pillar = _primitive(bpy.ops.mesh.primitive_cylinder_add, vertices=24, radius=0.3, depth=4.0)
    pillar.name = "Pillar"
    _smooth(pillar)
    for i in range(counts["pillars"]):
        x, y = spot()
        obj = place("Pillar%02d" % i, pillar, (x, y, 2.0), 32)
        bevel = obj.modifiers.new("Bevel", 'BEVEL')
        bevel.width = 0.05
        _subsurf(obj)
    tree = bpy.data.collections.new("Tree")
    trunk = _primitive(bpy.ops.mesh.primitive_cylinder_add, vertices=16, radius=0.25, depth=3.0)
    trunk.materials.append(mats[1])
    crown = _primitive(bpy.ops.mesh.primitive_ico_sphere_add, subdivisions=7, radius=1.8)
    crown.materials.append(mats[3])
    _smooth(crown)
    for name, mesh, z in (("Trunk", trunk, 1.5), ("Crown", crown, 4.2)):
        part = bpy.data.objects.new(name, mesh)
        part.location = (0.0, 0.0, z)
        tree.objects.link(part)
    for i in range(counts["trees"]):
        x, y = spot(radius=2.0)
        inst = bpy.data.objects.new("Tree%02d" % i, None)
        inst.instance_type = 'COLLECTION'
        inst.instance_collection = tree
        inst.location = (x, y, 0.0)
        coll.objects.link(inst)
    bench_courtyard.sun_and_sky(height=30.0)
    return objs, counts


STAGES = ("seconds_export", "seconds_setup", "seconds_direct", "seconds_trace", "seconds_writeback")


def scaling(one, two, full, cores=(2, 16, 64)):
    """Serial fraction of each stage, s = 2 T2 / T1 - 1 (Amdahl: T(p) = T1 (s + (1 - s) / p)), from the
    same fixed-photon bake on one core (`one`) and two (`two`), and the bake of `full` (2 cores) at
    `cores`: {stage: {"serial": s, "seconds": {p: T}}} and the totals."""
    out, total = {}, {p: 0.0 for p in cores}
    for stage in STAGES:
        t1, t2 = one["stages"].get(stage, 0.0), two["stages"].get(stage, 0.0)
        serial = min(1.0, max(0.0, 2.0 * t2 / t1 - 1.0)) if t1 > 0 else 1.0
        t1_full = full["stages"].get(stage, 0.0) / (serial + (1.0 - serial) / 2.0)
        seconds = {p: t1_full * (serial + (1.0 - serial) / p) for p in cores}
        out[stage] = dict(serial=serial, seconds=seconds)
        for p in cores:
            total[p] += seconds[p]
    out["total"] = dict(seconds=total)
    return out


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="bench_level.py")
    bench_courtyard.bake_arguments(ap, "/tmp/bench_level", bakes=1)
    ap.add_argument("--scale", type=float, default=1.0, help="multiplies every object count")
    ap.add_argument("--scene-file", action="store_true", help="also write DIR/scene/level.json (for `photonlm bake`)")
    ap.add_argument("--save", action="store_true", help="save the level with its UV maps to DIR/level.blend")
    ap.add_argument("--scaling", nargs=3, metavar=("ONE", "TWO", "FULL"),
                    help="no bake: the scaling model from level.json files of a fixed-photon bake on one core "
                         "and on two, and of the full level (their last bakes)")
    args = ap.parse_args(argv)
    if args.scaling:
        runs = []
        for path in args.scaling:
            with open(path) as f:
                runs.append(json.load(f)["bakes"][-1])
        model = scaling(*runs)
        for stage, m in model.items():
            print("%-18s serial %s  %s" % (stage, "%.3f" % m["serial"] if "serial" in m else "  -  ",
                                             "  ".join("%d cores %7.1f s" % (p, t) for p, t in m["seconds"].items())))
        with open(os.path.join(args.out, "scaling.json"), "w") as f:
            json.dump(model, f, indent=1)
        return
    os.makedirs(args.out, exist_ok=True)
    os.environ.setdefault("PHOTONLM_TEST_OUT", args.out)
    scenes.setup_paths()

    t0 = time.perf_counter()
    objs, counts = build(args.scale)
    seconds_build = time.perf_counter() - t0
    blender_triangles = bench_courtyard.evaluated_triangles(objs)  # evaluates the scene, as a viewport has
    print("level: %s; %d objects with lightmaps, %.2f M triangles in Blender's viewport meshes, built in %.1f s"
          % (counts, len(objs), blender_triangles / 1e6, seconds_build), flush=True)
    results = []
    for k in range(args.bakes):
        r = bench_courtyard.export_once(args, k) if args.export_only else bench_courtyard.bake_once(args, k)
        if not args.export_only:
            st = r["stages"]
            r["export_share"] = st["seconds_export"] / r["wall_seconds"]
            r["writeback_share"] = st.get("seconds_writeback", 0.0) / r["wall_seconds"]
            print("export %.1f %% and write-back %.1f %% of the bake's %.1f s"
                  % (100 * r["export_share"], 100 * r["writeback_share"], r["wall_seconds"]), flush=True)
        results.append(r)
    if args.scene_file:
        from photonlm_blender.bake import scene_file as scene_file_export
        path, _ = scene_file_export.export_scene_file(bpy.context, os.path.join(args.out, "scene", "level.json"))
        print("scene file:", path)
    if args.save:
        bpy.ops.wm.save_as_mainfile(filepath=os.path.join(args.out, "level.blend"))
    with open(os.path.join(args.out, "level.json"), "w") as f:
        json.dump(dict(scale=args.scale, counts=counts, blender_triangles=blender_triangles,
                       seconds_build=seconds_build, bakes=results), f, indent=1)


if __name__ == "__main__":
    main()
