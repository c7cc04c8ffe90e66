"""Subdivision surfaces: exporting the cage (refined by the engine with OpenSubdiv)
against exporting Blender's refined mesh. Runs in headless Blender:

    PHOTONLM_LIBRARY=$PWD/build/lib/libphotonlm.so PHOTONLM_SOURCE_DIR=$PWD \
        blender -b --factory-startup --python docs/bench_subdiv.py -- [--levels 2 3 4] [--photons 2000000]

Scene: Suzanne (500 faces, her own UV map as the `lightmap` UV, 256 x 256 texels) with a
Subdivision Surface modifier (levels = render levels = L), on a grey floor, lit by a sun and a
sky. Each (level, path) runs in its own Blender process so that peak memory (ru_maxrss) is its own.
Per run: Blender's evaluation of the modifier (depsgraph, paid by both paths when the modifier is
on in the viewport), the add-on's export (Python: reading arrays, the engine's add_mesh /
add_subdiv_mesh incl. OpenSubdiv refinement), bytes of numpy arrays handed to the engine, peak
Python allocation during export (tracemalloc), the bake (engine wall time), peak RSS of the
process. The two paths' lightmaps at the same seed are compared (relative RMS over covered texels).
Timings are wall-clock on a shared 2-core machine: noisy.
"""
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
import tracemalloc

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
SRC = os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(HERE)
sys.path.insert(0, os.path.join(SRC, "blend_tests"))
import scenes  # noqa: E402


def args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    out = {"levels": [2, 3, 4], "photons": 2_000_000, "child": None}
    i = 0
    while i < len(argv):
        if argv[i] == "--levels":
            out["levels"] = []
            i += 1
            while i < len(argv) and not argv[i].startswith("--"):
                out["levels"].append(int(argv[i]))
                i += 1
            continue
        if argv[i] == "--photons":
            out["photons"] = int(argv[i + 1])
        elif argv[i] == "--child":
            out["child"] = (int(argv[i + 1]), argv[i + 2], argv[i + 3])
            i += 2
        i += 1
    return out


def build(level):
    scenes.clear_scene()
    bpy.ops.mesh.primitive_monkey_add(size=2, location=(0, 0, 1.0), rotation=(0.3, 0, 0.4))
    suz = bpy.context.active_object
    suz.name = "Suzanne"
    suz.data.uv_layers[0].name = "lightmap"
    suz.photonlm.enabled = True
    suz.photonlm.resolution = 256
    mod = suz.modifiers.new("Subdivision", 'SUBSURF')
    mod.levels = level
    mod.render_levels = level
    bpy.ops.mesh.primitive_plane_add(size=8)
    floor = bpy.context.active_object
    grey = scenes.diffuse_material("grey", (0.6, 0.6, 0.6))
    suz.data.materials.append(grey)
    floor.data.materials.append(grey)
    scenes.add_light("Sun", 'SUN', (0, 0, 5), rotation=(0.6, 0.2, 0), energy=3.0)
    scenes.set_world_color((0.3, 0.35, 0.45), 1.0)
    return suz


def child(level, path, out_json, photons):
    scenes.setup_paths()
    import photonlm
    from photonlm_blender.export import scene as export
    from photonlm_blender.export import subdiv as subdiv_export
    from photonlm_blender.export import meshes
    native = path == "cage"
    t0 = time.perf_counter()
    suz = build(level)
    bpy.context.scene.photonlm.native_subdivision = native
    bpy.context.scene.photonlm.output_dir = tempfile.mkdtemp(prefix="bench_subdiv_")
    bpy.context.evaluated_depsgraph_get()  # Blender evaluates the modifier (both paths)
    t_eval = time.perf_counter() - t0
    # Data handed to the engine.
    if native:
        cage = subdiv_export.read_cage(suz.data, suz.matrix_world, level, True)
        nbytes, triangles = cage.nbytes(), cage.triangle_count()
    else:
        with meshes.evaluated_mesh(suz, bpy.context.evaluated_depsgraph_get()) as (_, mesh):
            pos, tris, mat, uv = meshes.mesh_arrays(mesh, suz.matrix_world, True)
        nbytes, triangles = pos.nbytes + tris.nbytes + mat.nbytes + uv.nbytes, len(tris)
        del pos, tris, mat, uv
    # Export alone, under tracemalloc (numpy reports its buffers to it).
    reports = export.Reports()
    tracemalloc.start()
    t1 = time.perf_counter()
    exp = export.export_scene(bpy.context, photonlm, reports)
    t_export = time.perf_counter() - t1
    py_peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    exp.scene.close()
    # The bake through the add-on's operator.
    last = scenes.photonlm_bake(photons, 8, seed=1, target_error=0.0, direct_samples=32)
    lm = last["objects"]["Suzanne"]
    npy = out_json[:-5] + ".npz"
    np.savez(npy, rgb=lm["rgb"], coverage=lm["coverage"])
    res = dict(level=level, path=path, triangles=triangles, bytes=nbytes, t_eval=t_eval, t_export=t_export,
               t_export_addon=last["stats"]["seconds_export"], t_bake=last["stats"]["seconds_total"],
               py_peak=py_peak, rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0, lightmap=npy,
               cage_note=any("refined by the engine" in t for _, t in last["reports"]))
    with open(out_json, "w") as f:
        json.dump(res, f)


def driver(levels, photons):
    tmp = tempfile.mkdtemp(prefix="bench_subdiv_")
    rows = []
    for level in levels:
        for path in ("mesh", "cage"):
            out = os.path.join(tmp, "%d_%s.json" % (level, path))
            cmd = [bpy.app.binary_path, "-b", "--factory-startup", "--python", os.path.abspath(__file__), "--",
                   "--child", str(level), path, out, "--photons", str(photons)]
            subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            with open(out) as f:
                rows.append(json.load(f))
            print("done level %d %s" % (level, path), flush=True)
    print("\n| level | path | triangles | data through Python | Blender eval (s) | export (s) | Python peak in export | bake (s) | peak RSS (MB) | lightmap vs mesh path (rel. RMS) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    by = {(r["level"], r["path"]): r for r in rows}
    for r in rows:
        ref = np.load(by[(r["level"], "mesh")]["lightmap"])
        me = np.load(r["lightmap"])
        mask = (ref["coverage"] > 0.999) & (me["coverage"] > 0.999)
        a, b = ref["rgb"].mean(axis=2)[mask], me["rgb"].mean(axis=2)[mask]
        rel = float(np.sqrt(np.mean((a - b) ** 2)) / a.mean())
        print("| %d | %s%s | %d | %.2f MB | %.3f | %.3f | %.2f MB | %.2f | %.0f | %s |" % (
            r["level"], r["path"], "" if r["path"] == "mesh" or r["cage_note"] else " (fell back!)", r["triangles"],
            r["bytes"] / 1e6, r["t_eval"], r["t_export"], r["py_peak"] / 1e6, r["t_bake"], r["rss_mb"],
            "-" if r["path"] == "mesh" else "%.1e" % rel))


a = args()
if a["child"]:
    child(*a["child"], a["photons"])
else:
    driver(a["levels"], a["photons"])
