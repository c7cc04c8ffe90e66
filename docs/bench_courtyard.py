"""Export and memory at scale: a courtyard of many subdivided, smooth-shaded objects baked through
the add-on in headless Blender, with the time of every stage and the peak memory.

    PHOTONLM_LIBRARY=$PWD/build/lib/libphotonlm.so PHOTONLM_SOURCE_DIR=$PWD \
        blender -b --factory-startup --python docs/bench_courtyard.py -- --out /tmp/bench_courtyard \
        [--objects 128] [--target 0.05] [--level 2] [--blender-subdiv] [--photons N] [--time-budget S]
        [--bakes 2] [--scene-file] [--profile] [--export-only] [--gltf]

Scene: a ground and four walls (boxes) around N Suzanne monkeys on the ground, each with a Subdivision
Surface modifier (render level --level, 2 by default: about 15,700 triangles a monkey) and smooth
shading, each with its own diffuse material and a 64 x 64 lightmap (the ground and the walls too);
the add-on makes every lightmap UV map. A sun (strength 3, 40 degrees up) and a Nishita sky light it.
With 128 monkeys: 133 objects, about 2.0 M triangles, 545 k texels.

The bake runs through the add-on's operator (bpy.ops.photonlm.bake, as an artist bakes), with
Target Error --target, Max Photons --photons (0: the add-on's default cap), Time Budget
--time-budget (0: none) and the add-on's other defaults, --bakes times: the first bake makes the lightmap UV maps and renders the sky, later ones
reuse both (as a second bake of an unchanged scene does). The scene is evaluated once before the
first bake (an artist's scene is, by the viewport). By default the add-on exports the monkeys
as their cages and the engine refines them (Native Subdivision); --blender-subdiv exports Blender's
subdivided meshes instead (every triangle then passes through the export). --profile runs the bake
(or the export) under cProfile and writes the 40 most expensive functions to DIR/profile_<k>.txt.
--export-only runs only the add-on's export (as the operator does, lightmap UV maps kept), --bakes
times, and no bake: the export stages in about a minute. The export (and the engine's refinement
of the cages in it) uses every core the process may run on: `taskset -c 0 blender ...` measures
one thread.

Printed and written to DIR/courtyard.json, per bake: objects, triangles (as the engine sees them),
texels, the add-on's per-stage seconds (export stages, engine set-up / photons / direct, write-back)
and the export stages' CPU seconds (of the main thread, and the whole export's of all threads;
on a busy machine the wall times include waiting for a core), the operator's wall time, peak memory (getrusage maxrss of the Blender process, and before the
bake), the engine's own memory estimate, the error estimate reached and whether the photon cap or
the time budget stopped the bake before the target. --scene-file writes the scene for the engine
alone, whose memory can then be measured apart from Blender's:

    /usr/bin/time -v ./build/bin/photonlm bake DIR/scene/courtyard.json -o DIR/cli --photons 2000000
"""
import argparse
import json
import math
import os
import random
import resource
import sys
import time

import bpy

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(HERE)
sys.path.insert(0, os.path.join(SRC, "blend_tests"))
import scenes  # noqa: E402

RES = 64


def _material(name, color):
    return scenes.diffuse_material(name, color)


def box_mesh(name, size):
    """A box mesh of `size` (x, y, z) centred at its origin."""
    mesh = bpy.data.meshes.new(name)
    hx, hy, hz = (s / 2.0 for s in size)
    verts = [(sx * hx, sy * hy, sz * hz) for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    return mesh


def _box(name, center, size, color):
    """A box object of `size` (x, y, z) centred at `center`, its own material, a 64 x 64 lightmap."""
    obj = bpy.data.objects.new(name, box_mesh(name, size))
    obj.location = center
    obj.data.materials.append(_material(name, color))
    obj.photonlm.enabled = True
    obj.photonlm.resolution = RES
    bpy.context.scene.collection.objects.link(obj)
    return obj


def build(count, level, seed=7):
    """The courtyard: ground, four walls, `count` subdivided smooth monkeys. Returns the objects."""
    scenes.clear_scene()
    cols = max(1, math.ceil(math.sqrt(count * 2.0)))
    rows = max(1, math.ceil(count / cols))
    spacing = 2.2
    half_x, half_y = cols * spacing / 2.0 + 1.5, rows * spacing / 2.0 + 1.5
    objs = [_box("Ground", (0, 0, -0.1), (2 * half_x, 2 * half_y, 0.2), (0.5, 0.5, 0.45))]
    wall_h, t = 3.0, 0.3
    objs.append(_box("WallNorth", (0, half_y + t / 2, wall_h / 2), (2 * half_x + 2 * t, t, wall_h), (0.7, 0.6, 0.5)))
    objs.append(_box("WallSouth", (0, -half_y - t / 2, wall_h / 2), (2 * half_x + 2 * t, t, wall_h), (0.7, 0.6, 0.5)))
    objs.append(_box("WallEast", (half_x + t / 2, 0, wall_h / 2), (t, 2 * half_y, wall_h), (0.6, 0.65, 0.7)))
    objs.append(_box("WallWest", (-half_x - t / 2, 0, wall_h / 2), (t, 2 * half_y, wall_h), (0.6, 0.65, 0.7)))
    bpy.ops.mesh.primitive_monkey_add(size=1.6)
    proto = bpy.context.active_object
    proto_mesh = proto.data
    bpy.data.objects.remove(proto)
    rng = random.Random(seed)
    for i in range(count):
        r, c = divmod(i, cols)
        mesh = proto_mesh.copy()
        mesh.name = "Monkey%03d" % i
        mesh.polygons.foreach_set("use_smooth", [True] * len(mesh.polygons))
        mesh.update()
        obj = bpy.data.objects.new("Monkey%03d" % i, mesh)
        obj.location = ((c - (cols - 1) / 2.0) * spacing, (r - (rows - 1) / 2.0) * spacing, 0.6)
        obj.rotation_euler = (math.radians(-20.0), 0.0, math.radians(rng.uniform(-60.0, 60.0)))
        mod = obj.modifiers.new("Subdivision", 'SUBSURF')
        mod.levels = level
        mod.render_levels = level
        obj.data.materials.append(_material("Monkey%03d" % i, (rng.uniform(0.3, 0.8), rng.uniform(0.3, 0.8),
                                                              rng.uniform(0.3, 0.8))))
        obj.photonlm.enabled = True
        obj.photonlm.resolution = RES
        bpy.context.scene.collection.objects.link(obj)
        objs.append(obj)
    bpy.data.meshes.remove(proto_mesh)
    sun_and_sky()
    return objs


def sun_and_sky(height=10.0):
    """A sun lamp (strength 3, 40 degrees up) and a physical sky without its sun disc, strength 0.3."""
    scenes.add_light("Sun", 'SUN', (0, 0, height), rotation=(math.radians(50.0), 0.0, math.radians(30.0)),
                     energy=3.0, angle=math.radians(1.0))
    nt = bpy.context.scene.world.node_tree
    sky = nt.nodes.new('ShaderNodeTexSky')
    sky.sky_type = scenes.physical_sky_type()
    sky.sun_disc = False  # the sun lamp is the sun
    sky.sun_elevation = math.radians(40.0)
    sky.sun_rotation = math.radians(120.0)
    bg = nt.nodes['Background']
    nt.links.new(sky.outputs['Color'], bg.inputs['Color'])
    bg.inputs['Strength'].default_value = 0.3


def evaluated_triangles(objs):
    """Triangles of the evaluated meshes (what Blender's subdivided meshes hold)."""
    dg = bpy.context.evaluated_depsgraph_get()
    total = 0
    for o in objs:
        e = o.evaluated_get(dg)
        m = e.to_mesh()
        m.calc_loop_triangles()
        total += len(m.loop_triangles)
        e.to_mesh_clear()
    return total


def maxrss_bytes():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def rss_bytes():
    """Resident memory now."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def bake_arguments(ap, out, bakes):
    """The options bake_once and export_once read (args.out, target, photons, time_budget, profile),
    with --bakes and --export-only."""
    ap.add_argument("--out", default=out)
    ap.add_argument("--target", type=float, default=0.05, help="the bake's Target Error")
    ap.add_argument("--photons", type=int, default=0, help="Max Photons (0: the add-on's default)")
    ap.add_argument("--time-budget", type=float, default=0.0, help="Time Budget in seconds (0: none)")
    ap.add_argument("--bakes", type=int, default=bakes, help="bakes in a row (the first makes the UV maps)")
    ap.add_argument("--profile", action="store_true", help="cProfile each bake into DIR/profile_<k>.txt")
    ap.add_argument("--export-only", action="store_true", help="export only, no engine bake (export stages)")


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser(prog="bench_courtyard.py")
    bake_arguments(ap, "/tmp/bench_courtyard", bakes=2)
    ap.add_argument("--objects", type=int, default=128, help="monkeys on the ground")
    ap.add_argument("--level", type=int, default=2, help="subdivision level of the monkeys")
    ap.add_argument("--blender-subdiv", action="store_true",
                    help="export Blender's subdivided meshes (Native Subdivision off)")
    ap.add_argument("--gltf", action="store_true",
                    help="after the bakes, File > Export > glTF with PhotonLM lightmaps: DIR/courtyard.glb, its time and size")
    ap.add_argument("--scene-file", action="store_true",
                    help="also write the scene as a scene file, DIR/scene/courtyard.json (for `photonlm bake`)")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    os.environ.setdefault("PHOTONLM_TEST_OUT", args.out)
    scenes.setup_paths()

    t0 = time.perf_counter()
    objs = build(args.objects, args.level)
    seconds_build = time.perf_counter() - t0
    scene = bpy.context.scene
    scene.photonlm.native_subdivision = not args.blender_subdiv
    blender_triangles = evaluated_triangles(objs)  # also evaluates the scene, as a viewport would have
    results = []
    for k in range(args.bakes):
        results.append(export_once(args, k) if args.export_only else bake_once(args, k))
    gltf = gltf_export(args) if args.gltf else None
    if args.scene_file:
        from photonlm_blender.bake import scene_file as scene_file_export
        path, _ = scene_file_export.export_scene_file(bpy.context, os.path.join(args.out, "scene", "courtyard.json"))
        print("scene file:", path)
    with open(os.path.join(args.out, "courtyard.json"), "w") as f:
        json.dump(dict(monkeys=args.objects, level=args.level, native_subdivision=not args.blender_subdiv,
                       blender_triangles=blender_triangles, seconds_build=seconds_build, bakes=results, gltf=gltf),
                  f, indent=1)


def gltf_export(args):
    """The .glb of the baked courtyard (the glTF exporter finds the add-on's hook among enabled add-ons)."""
    import addon_utils
    addon_utils.enable("io_scene_gltf2", default_set=True)
    addon_utils.enable("photonlm_blender", default_set=True)
    from photonlm_blender.gltf.export import export_glb
    path = os.path.join(args.out, "courtyard.glb")
    t0 = time.perf_counter()
    summary = export_glb(bpy.context, path)
    seconds = time.perf_counter() - t0
    texels = sum(bpy.data.images[name].size[0] * bpy.data.images[name].size[1] for name in summary["textures"]
                 if name in bpy.data.images)
    png = sum(t["png_bytes"] for t in summary["textures"].values())
    out = dict(seconds=seconds, bytes=summary["size"], objects=len(summary["objects"]), texels=texels, png_bytes=png)
    print("glTF: %d objects in %.1f s, %.1f MB (lightmap PNGs %.2f MB per million texels)"
          % (out["objects"], seconds, summary["size"] / 1e6, png / texels))
    return out


def export_once(args, k):
    """The operator's export alone (bake.BakeJob), its lightmap UV maps kept; the engine's scene is
    released unbaked. Per-stage seconds and CPU seconds as bake_once prints them."""
    from photonlm_blender.bake import job as bake
    from photonlm_blender.uv import uvmaps
    if args.profile:
        import cProfile
        import pstats
        prof = cProfile.Profile()
        prof.enable()
    t0 = time.perf_counter()
    job = bake.BakeJob(bpy.context)
    wall = time.perf_counter() - t0
    if args.profile:
        prof.disable()
        with open(os.path.join(args.out, "profile_%d.txt" % k), "w") as f:
            pstats.Stats(prof, stream=f).sort_stats("cumulative").print_stats(40)
            pstats.Stats(prof, stream=f).sort_stats("tottime").print_stats(40)
    uvmaps.commit(job.created_uvs)
    job.created_uvs = []
    triangles = int(job.manifest.triangles)
    job.export.scene.close()
    job.export.texture_files.cleanup()
    stages = {"seconds_" + key: float(v) for key, v in job.times.seconds.items()}
    stages["seconds_export"] = float(job.seconds_export)
    cpu = {"cpu_seconds_" + key: float(v) for key, v in job.times.cpu.items()}
    result = dict(bake=k + 1, objects=len(job.manifest.baked), triangles=triangles, wall_seconds=wall,
                  stages=stages, cpu=cpu, cpu_seconds_export=job.cpu_seconds_export,
                  cpu_seconds_export_process=job.cpu_seconds_export_process,
                  export_seconds_per_million_triangles=job.seconds_export / (triangles / 1e6),
                  export_cpu_seconds_per_million_triangles=job.cpu_seconds_export / (triangles / 1e6),
                  export_process_cpu_seconds_per_million_triangles=job.cpu_seconds_export_process / (triangles / 1e6),
                  cores=len(os.sched_getaffinity(0)))
    print("export %d: %d objects, %.2f M triangles, native subdivision %s, %d cores"
          % (k + 1, result["objects"], triangles / 1e6, bpy.context.scene.photonlm.native_subdivision,
             result["cores"]))
    for key, v in sorted(stages.items()):
        c = cpu.get("cpu_" + key)
        print("  %-32s %8.3f s%s" % (key, v, "  (CPU %.3f s)" % c if c is not None else ""))
    print("export %.3f s = %.3f s per M triangles; CPU %.3f s of the main thread = %.3f s per M, "
          "%.3f s of all threads = %.3f s per M"
          % (job.seconds_export, result["export_seconds_per_million_triangles"], job.cpu_seconds_export,
             result["export_cpu_seconds_per_million_triangles"], job.cpu_seconds_export_process,
             result["export_process_cpu_seconds_per_million_triangles"]), flush=True)
    return result


def bake_once(args, k):
    from photonlm_blender.properties import scene as properties
    scene = bpy.context.scene
    s = scene.photonlm
    rss_before, rss_now = maxrss_bytes(), rss_bytes()
    photon_cap = args.photons or int(properties.PHOTON_CAP_DEFAULT)
    if args.profile:
        import cProfile
        import pstats
        prof = cProfile.Profile()
        prof.enable()
    last = scenes.photonlm_bake(photon_cap, int(s.max_bounces), seed=int(s.seed) + k, target_error=args.target,
                                time_budget=args.time_budget, output_dir=os.path.join(args.out, "lightmaps"))
    if args.profile:
        prof.disable()
        with open(os.path.join(args.out, "profile_%d.txt" % k), "w") as f:
            pstats.Stats(prof, stream=f).sort_stats("cumulative").print_stats(40)
            pstats.Stats(prof, stream=f).sort_stats("tottime").print_stats(40)
    wall = last["wall_seconds"]
    engine = last["stats"]
    texels = sum(o["size"][0] * o["size"][1] for o in last["objects"].values())
    stages = {key: float(v) for key, v in engine.items() if key.startswith("seconds_")}
    cpu = {key: float(v) for key, v in engine.items() if key.startswith("cpu_seconds_")}
    triangles = int(engine["triangles"])
    export_s = stages["seconds_export"]
    time_budget = float(s.time_budget)
    reached = float(engine["error_estimate"]) <= args.target
    result = dict(
        bake=k + 1, objects=len(last["objects"]), triangles=triangles, texels=texels,
        wall_seconds=wall, stages=stages, cpu=cpu,
        export_seconds_per_million_triangles=export_s / (triangles / 1e6) if triangles else 0.0,
        export_cpu_seconds_per_million_triangles=cpu["cpu_seconds_export"] / (triangles / 1e6) if triangles else 0.0,
        peak_rss=maxrss_bytes(), peak_rss_before_bake=rss_before, rss_at_bake_start=rss_now, rss_after_bake=rss_bytes(),
        memory_estimate=float(engine["memory_estimate"]),
        photons=int(engine["photons_emitted"]), photon_cap=photon_cap, time_budget=time_budget,
        direct_samples=int(engine["direct_samples"]), rays_traced=int(engine["rays_traced"]),
        target_error=args.target, error_estimate=float(engine["error_estimate"]),
        error_p95=float(engine["error_p95"]),
        target_reached=reached,
        stopped_by_cap=(not reached) and photon_cap > 0 and int(engine["photons_emitted"]) >= photon_cap,
        stopped_by_budget=(not reached) and time_budget > 0 and float(engine["seconds_total"]) >= 0.98 * time_budget,
        warnings=list(last["warnings"]))
    print("bake %d: %d objects, %.2f M triangles, %d texels, native subdivision %s"
          % (k + 1, result["objects"], triangles / 1e6, texels, s.native_subdivision))
    for key, v in sorted(stages.items()):
        c = cpu.get("cpu_" + key)
        print("  %-32s %8.3f s%s" % (key, v, "  (CPU %.3f s)" % c if c is not None else ""))
    print("export CPU of all threads %.3f s" % cpu["cpu_seconds_export_process"])
    print("wall %.2f s, export %.3f s = %.3f s per M triangles (CPU %.3f s per M); peak RSS %.2f GB (%.2f GB "
          "before the bake; resident %.2f GB at its start, %.2f GB after), engine estimate %.2f GB"
          % (wall, export_s, result["export_seconds_per_million_triangles"],
             result["export_cpu_seconds_per_million_triangles"], result["peak_rss"] / 1e9, rss_before / 1e9,
             rss_now / 1e9, result["rss_after_bake"] / 1e9, result["memory_estimate"] / 1e9))
    print("error %.2f %% (target %.2f %%, %s), %d photons (cap %d)%s"
          % (100 * result["error_estimate"], 100 * args.target, "reached" if reached else "not reached",
             result["photons"], photon_cap, ", stopped by the photon cap" if result["stopped_by_cap"] else
             ", stopped by the time budget" if result["stopped_by_budget"] else ""), flush=True)
    return result

if __name__ == "__main__":
    main()
