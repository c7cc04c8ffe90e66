"""Scene file export and batch baking: what the add-on bakes in Blender, the CLI bakes from the
exported scene file, and scripts/bake_blend.sh bakes from a saved .blend, give the same lightmaps.

Scene: the Cornell box (area light, seven objects, three materials) plus a spot light, a world
colour, a geometry-only quad with two materials (per-triangle materials in the file) and the
tall box on an orientation lightmap (an OL group in the file), and a small cube with a Subdivision
Surface modifier (level 2, one creased edge) that both the add-on and the file carry as its cage
(the engine refines it; no fallback to Blender's refined mesh).

1. Bake with the add-on's operator (fixed photon count, seed 7, 2 threads).
2. File > Export > PhotonLM scene: the file holds the scene's settings and, in "metadata", each
   object's mesh and the EXR `photonlm bake` writes for it. Export again with every mesh in an
   OBJ sidecar file (usemtl runs for the per-triangle materials).
3. `photonlm bake` each file (--threads 1: results depend on the seed only, not on threads).
   Expected: every lightmap and the OL equal the add-on's bake bit for bit: the file holds the
   same float32 numbers the bridge passes to the engine (floats written exactly), the bake
   settings and seed are the same, and the engine's result depends on the seed only (not on the
   threads, nor on the host process: in Blender 4.3 and 5.2 the engine inside Blender reaches its
   own Embree, not Blender's). Any export mismatch (a missing light, a wrong material, a
   transposed matrix, lost UVs) moves texels by percent.
4. scripts/bake_blend.sh on the saved .blend (-o DIR --save): exit 0, prints the error estimate,
   writes the same lightmaps (bit for bit), and the saved .blend links the images to them.
   On a .blend with nothing to bake and on a missing file it exits non-zero with a message.
"""
import json
import os
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

PHOTONS = 150_000
SEED = 7


def build_scene():
    scenes.clear_scene()
    objs = scenes.cornell_box(resolution=16)
    scenes.add_light("spot", 'SPOT', (0.5, -0.8, 1.6), rotation=(0.6, 0.3, 0.0), energy=30.0,
                     spot_size=0.9, spot_blend=0.3, shadow_soft_size=0.05, color=(1.0, 0.9, 0.7))
    scenes.set_world_color((0.05, 0.06, 0.08))
    blue = scenes.diffuse_material("blue", (0.1, 0.2, 0.7))
    yellow = scenes.diffuse_material("yellow", (0.7, 0.6, 0.1))
    panel = scenes.quads_object("panel", [((-0.9, 0.5, 0.3), (-0.5, 0.5, 0.3), (-0.5, 0.9, 0.8), (-0.9, 0.9, 0.8),
                                           (0, 0, 1, 1)),
                                          ((-0.5, 0.5, 0.3), (-0.1, 0.5, 0.3), (-0.1, 0.9, 0.8), (-0.5, 0.9, 0.8),
                                           (0, 0, 1, 1))], blue, 8)
    panel.data.materials.append(yellow)
    panel.data.polygons[1].material_index = 1
    panel.photonlm.enabled = False  # geometry only, two materials
    objs["tall_box"].photonlm.mode = 'ORIENTATION'
    objs["tall_box"].photonlm.ol_resolution = 8
    bpy.ops.mesh.primitive_cube_add(size=0.3, location=(0.55, 0.55, 0.25))
    blob = bpy.context.active_object
    blob.name = "blob"
    blob.data.uv_layers[0].name = "lightmap"  # Blender's fixed cube layout: the same in every process
    scenes.set_edge_crease(blob.data, 0, 1.0)
    blob.data.materials.append(yellow)
    mod = blob.modifiers.new("Subdivision", 'SUBSURF')
    mod.levels = mod.render_levels = 2
    objs["blob"] = blob
    return objs


def run(cmd, timeout=300):
    print("$ " + " ".join(cmd), flush=True)
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    print(r.stdout[-3000:], r.stderr[-3000:], flush=True)
    return r


def compare(checks, what, ours, files):
    """ours: {object: (h, w, 3)}; files: {object: EXR path}."""
    worst, scale, missing = 0.0, 0.0, []
    for name, rgb in ours.items():
        if name not in files or not os.path.isfile(files[name]):
            missing.append(name)
            continue
        other = scenes.exr_rgb(files[name])
        if other.shape != rgb.shape:
            missing.append("%s (shape %s, want %s)" % (name, other.shape, rgb.shape))
            continue
        worst = max(worst, float(np.max(np.abs(other - rgb))))
        scale = max(scale, float(np.max(rgb)))
    checks.check(not missing and scale > 0 and worst == 0.0,
                 "%s: %d lightmaps equal the add-on's bake bit for bit: max |diff| %.3g (max texel %.4g)%s"
                 % (what, len(ours), worst, scale, "; missing: %s" % missing if missing else ""))


def main():
    checks = scenes.Checks("scene_file_export")
    scenes.setup_paths()
    from photonlm_blender.bake import scene_file as scene_file_export
    out = scenes.out_dir("scene_file_export")
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    cli = scenes.cli_path()
    checks.check(os.access(cli, os.X_OK), "the photonlm CLI is at %s" % cli)

    build_scene()
    bpy.context.scene.photonlm.output_dir = os.path.join(out, "addon")
    last = scenes.photonlm_bake(PHOTONS, 64, seed=SEED, target_error=0.0, direct_samples=16)
    ours = {name: np.array(o["rgb"], np.float32) for name, o in last["objects"].items()}
    ol_ours = {g: scenes.exr_rgb(o["path"]) for g, o in last["ols"].items()}
    checks.check(len(ours) == 8 and len(ol_ours) == 1,
                 "the add-on baked 8 lightmaps and 1 OL (%d, %d)" % (len(ours), len(ol_ours)))

    # ---- export: operator (inline meshes) and function (every mesh in an OBJ file) ----------------
    scene_json = os.path.join(out, "inline", "cornell.json")
    res = bpy.ops.photonlm.export_scene_file(filepath=scene_json)
    checks.check(res == {'FINISHED'} and os.path.isfile(scene_json), "the export operator wrote %s" % scene_json)
    with open(scene_json) as f:
        doc = json.load(f)
    st = doc.get("settings", {})
    checks.check(st.get("photon_count") == PHOTONS and st.get("seed") == SEED and st.get("target_error") == 0.0
                 and st.get("direct_samples") == 16 and st.get("max_bounces") == 64,
                 "the file holds the scene's bake settings: %s" % st)
    kinds = sorted(l["type"] for l in doc.get("lights", []))
    checks.check(kinds == ["AREA_RECT", "SPOT"] and "world" in doc and len(doc.get("ol_groups", [])) == 1
                 and any("materials" in m for m in doc["meshes"]) and len(doc["meshes"]) == 9,
                 "the file holds 9 meshes (one with per-triangle materials), lights %s, the world, 1 OL group" % kinds)
    meta = doc.get("metadata", {})
    files = {o["object"]: o["lightmap_file"] for o in meta.get("objects", [])}
    checks.check(sorted(files) == sorted(ours) and all(doc["meshes"][o["mesh"]]["name"] == o["object"]
                                                       for o in meta["objects"]),
                 "metadata names each object's mesh and EXR file: %s" % files)
    obj_json = os.path.join(out, "obj", "cornell.json")
    from photonlm_blender.export import scene as export
    reports = export.Reports()
    scene_file_export.export_scene_file(bpy.context, obj_json, reports=reports, obj_threshold=0)
    with open(obj_json) as f:
        doc_obj = json.load(f)
    checks.check(all(("obj" in m) == (m["name"] != "blob") for m in doc_obj["meshes"]),
                 "threshold 0: every mesh but the cage is an OBJ sidecar file (cages stay inline)")
    for label, d in (("inline", doc), ("obj", doc_obj)):
        blob = [m for m in d["meshes"] if m["name"] == "blob"]
        sd = blob[0].get("subdivision", {}) if blob else {}
        checks.check(sd.get("level") == 2 and sd.get("face_sizes") == [4] * 6 and len(sd.get("creases", [])) == 1
                     and sd["creases"][0][2] == 1.0 and len(blob[0]["indices"]) == 24
                     and len(blob[0].get("lightmap_uv", [])) == 48,
                     "%s file: the subdivided cube is its cage (level 2, 6 quads, 1 crease, UV per corner): %s"
                     % (label, sd))
    texts = [t for _, t in reports.items]
    checks.check(any("'blob': subdivision level 2 refined by the engine" in t for t in texts)
                 and not any("Blender's subdivided mesh" in t for t in texts),
                 "the export reports the cage, no fallback to Blender's mesh: %s"
                 % [t for t in texts if "blob" in t])

    # ---- the command the export suggests reads the file whatever its size -----------------------------
    command = scene_file_export.bake_command(scene_json)
    big = os.path.join(out, "big.json")
    with open(big, "wb") as f:
        f.truncate(300 << 20)  # sparse: 300 MiB, over the CLI's 256 MiB
    big_command = scene_file_export.bake_command(big)
    os.remove(big)
    checks.check(command.endswith("-o DIR") and big_command.endswith("-o DIR --max-file-mb 300"),
                 "the suggested commands: %s; %s" % (command, big_command))

    # ---- the CLI bakes the files -----------------------------------------------------------------------
    for label, path in (("inline", scene_json), ("obj", obj_json)):
        cli_out = os.path.join(out, label, "baked")
        r = run([cli, "bake", path, "-o", cli_out, "--threads", "1"])
        checks.check(r.returncode == 0, "photonlm bake %s exit code %d" % (label, r.returncode))
        if r.returncode != 0:
            continue
        with open(os.path.join(cli_out, "report.json")) as f:
            report = json.load(f)
        checks.check(sorted(m["file"] for m in report["meshes"]) == sorted(files.values()),
                     "%s: the CLI wrote the files the metadata names" % label)
        compare(checks, "CLI from the %s scene file" % label, ours,
                {n: os.path.join(cli_out, f) for n, f in files.items()})
        ol_file = meta["ol_groups"][0]["ol_file"]
        compare(checks, "CLI OL from the %s scene file" % label, ol_ours,
                {g: os.path.join(cli_out, ol_file) for g in ol_ours})

    # ---- headless .blend bake ------------------------------------------------------------------------
    src = os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    script = os.path.join(src, "scripts", "bake_blend.sh")
    blend = os.path.join(out, "cornell.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    head_out = os.path.join(out, "headless")
    r = run([script, blend, "-o", head_out, "--photons", str(PHOTONS), "--seed", str(SEED),
             "--target-error", "0", "--save"])
    checks.check(r.returncode == 0 and "error estimate" in r.stdout,
                 "bake_blend.sh exit code %d, prints the error estimate" % r.returncode)
    compare(checks, "bake_blend.sh", ours, {n: os.path.join(head_out, n + "_lightmap.exr") for n in ours})
    with bpy.data.libraries.load(blend, link=True) as (src_data, dst_data):
        dst_data.images = [n for n in src_data.images if n.endswith("_lightmap")]
    linked = {im.name: bpy.path.abspath(im.filepath, library=im.library) for im in dst_data.images if im}
    checks.check(len(linked) == 8 and all(os.path.normpath(p).startswith(os.path.normpath(head_out))
                                          for p in linked.values()),
                 "the saved .blend links 8 lightmap images to the EXRs in %s" % head_out)

    empty = os.path.join(out, "empty.blend")
    scenes.clear_scene()
    bpy.ops.wm.save_as_mainfile(filepath=empty, copy=True)
    r = run([script, empty])
    checks.check(r.returncode != 0 and "nothing to bake" in r.stderr,
                 "nothing to bake: exit code %d with a message" % r.returncode)
    r = run([script, os.path.join(out, "missing.blend")])
    checks.check(r.returncode != 0 and "no such file" in r.stderr, "missing file: exit code %d" % r.returncode)
    checks.finish()


main()
