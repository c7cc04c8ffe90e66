"""File > Import > PhotonLM bake folder: a farm's bake comes back into Blender as a bake in Blender
does.

Scene: the Cornell box (seven objects with fixed lightmap layouts, an area light) plus a spot light,
a world colour and a cube traced as an exact CSG box (its lightmap lives on its mesh).

1. File > Export > PhotonLM scene (the operator); the CLI bakes the file as a farm does:
   `photonlm bake --shard 1/2` and `--shard 2/2`, then `photonlm merge` into a folder.
2. The add-on bakes the same scene in Blender (same seed, photon count, settings) and the material
   node setups, images and statistics are recorded; then the preview nodes and images are removed.
3. The folder is imported with the operator. Expected, against truth:
   - each image holds the folder's EXR bit for bit (pixels against the EXR read by the engine's
     reader; the copied file byte for byte), linked (not packed) from the scene's lightmap folder
     under the name an in-Blender bake gives it; with Pack on, packed;
   - every material's node setup (nodes by role, their images, UV maps, links and values) equals the
     one the in-Blender bake made;
   - the lighting equals the in-Blender bake's to max |diff| <= 1e-5 x the largest texel: the file
     holds the bridge's float32 values exactly, sharded and merged bakes equal the single bake bit
     for bit (docs/farm.md), and the engine's result depends on the seed only, not on threads, so
     only float summation order can differ; a mapping error (the wrong object's EXR, a flipped or
     shifted image) moves texels by far more;
   - the Last Bake statistics are the report's (photons, error, times) and the in-Blender bake's
     to within float noise; per object, the covered texels and those above twice the error (the
     report's counts) and the Noisiest hint equal the in-Blender bake's; from a report without the
     counts, the texels with photon hits are counted.
4. Orientation lightmaps (a plain `photonlm bake`: shards refuse OL groups): an object's own and a
   collection's holding a geometry-only object. Both OL images are imported bit for bit, equal the
   in-Blender bake's (same tolerance), list the bake's objects, and the node setups equal the
   in-Blender bake's (the geometry-only object looks its light up in the collection's OL).
5. Bad input, each refused by the operator with a message naming the fault, nothing changed, Blender
   alive: no such folder, a folder without report.json, a folder of shard parts (and a Slurm folder
   whose merge did not run), a report that is not JSON, a report of another scene (no object
   matches), a missing EXR, an unreadable EXR, an EXR of the wrong size. A report with one object
   the .blend lacks (renamed): a warning naming it, the rest imported.
6. Layout Atlas: the imported lightmaps are packed into the same pages (bit for bit: R, G, B, error,
   hits), blocks and node setups as an in-Blender atlas bake makes.
7. In a saved .blend with the folder //lightmaps/, the images link their copies relative to it.
"""
import filecmp
import json
import os
import shutil
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

PHOTONS = 120_000
SEED = 11
TOL = 1e-5


def run(cmd, timeout=300):
    print("$ " + " ".join(cmd), flush=True)
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    print(r.stdout[-2000:], r.stderr[-2000:], flush=True)
    return r


def build_scene():
    scenes.clear_scene()
    objs = scenes.cornell_box(resolution=16)
    scenes.add_light("spot", 'SPOT', (0.5, -0.8, 1.6), rotation=(0.6, 0.3, 0.0), energy=30.0,
                     spot_size=0.9, spot_blend=0.3, shadow_soft_size=0.05, color=(1.0, 0.9, 0.7))
    scenes.set_world_color((0.05, 0.06, 0.08))
    bpy.ops.mesh.primitive_cube_add(size=0.3, location=(0.55, 0.2, 0.15))
    cube = bpy.context.active_object
    cube.name = "csg_cube"
    cube.data.uv_layers[0].name = "lightmap"  # Blender's fixed cube layout
    cube.data.materials.append(scenes.diffuse_material("mat_cube", (0.2, 0.4, 0.7)))
    cube.photonlm.primitive = 'BOX'
    cube.photonlm.resolution = 16
    objs["csg_cube"] = cube
    s = bpy.context.scene.photonlm
    s.photons, s.target_error, s.max_bounces, s.seed, s.direct_samples = PHOTONS, 0.0, 64, SEED, 16
    return objs


def image_rgb(image):
    w, h = image.size
    px = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    return px.reshape(h, w, 4)[..., :3].copy()


def wiring(mat):
    """A material's node setup: nodes by their PhotonLM role (else their name), type, image, UV map,
    unlinked input values; links between them; the active output."""
    from photonlm_blender.export import materials
    tree = mat.node_tree

    def key(n):
        return str(n.get(materials.TAG) or n.name)

    def value(v):
        try:
            return tuple("%.4g" % x for x in v)
        except TypeError:
            return "%.4g" % v if isinstance(v, float) else str(v)
    nodes = []
    for n in tree.nodes:
        inputs = tuple((s.identifier, value(s.default_value)) for s in n.inputs
                       if not s.is_linked and hasattr(s, "default_value"))
        nodes.append((key(n), n.bl_idname, getattr(getattr(n, "image", None), "name", None),
                      getattr(n, "uv_map", None), getattr(n, "target", None), n.mute, inputs))
    links = sorted((key(l.from_node), l.from_socket.identifier, key(l.to_node), l.to_socket.identifier)
                   for l in tree.links)
    active = [key(n) for n in tree.nodes if n.bl_idname == 'ShaderNodeOutputMaterial' and n.is_active_output]
    return sorted(nodes), links, active


def snapshot(objs):
    return {o.active_material.name: wiring(o.active_material) for o in objs}


class Layout:
    """Stands in for bpy.types.UILayout: records the labels and operators a panel draws."""

    def __init__(self, lines):
        object.__setattr__(self, "lines", lines)

    def __setattr__(self, name, value):  # use_property_split, scale_y, enabled...: ignored
        pass

    def _child(self, *args, **kwargs):
        return Layout(self.lines)

    column = row = box = split = _child

    def label(self, text="", icon='NONE', **kwargs):
        self.lines.append(("label", text))

    def prop(self, data, name, text=None, **kwargs):
        self.lines.append(("prop", name))

    def operator(self, idname, text=None, **kwargs):
        self.lines.append(("operator", idname))


def drawn(panel_class):
    lines = []

    class Panel:
        layout = Layout(lines)
    panel_class.draw(Panel, bpy.context)
    return lines


def import_folder(folder):
    """The operator's result and its error message ('' when none)."""
    try:
        return bpy.ops.photonlm.import_bake_folder(directory=folder), ""
    except RuntimeError as e:  # an operator that reports an error raises it here
        return {'CANCELLED'}, str(e)


def main():
    checks = scenes.Checks("import_bake_folder")
    scenes.setup_paths()
    import photonlm
    from photonlm_blender.writeback import record
    from photonlm_blender.writeback import images
    from photonlm_blender.writeback import wiring
    out = scenes.out_dir("import_bake_folder")
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    cli = scenes.cli_path()
    checks.check(os.access(cli, os.X_OK), "the photonlm CLI is at %s" % cli)

    objs = build_scene()
    baked_objs = [o for n, o in objs.items() if n != "light"]
    scene = bpy.context.scene

    # ---- 1. export and the farm's bake -------------------------------------------------------------
    scene_json = os.path.join(out, "farm", "scene.json")
    res = bpy.ops.photonlm.export_scene_file(filepath=scene_json)
    checks.check(res == {'FINISHED'}, "the export operator wrote %s" % scene_json)
    parts, merged = os.path.join(out, "farm", "parts"), os.path.join(out, "farm", "out")
    for k in (2, 1):  # any order
        r = run([cli, "bake", scene_json, "--shard", "%d/2" % k, "-o", parts, "--threads", "1"])
        checks.check(r.returncode == 0, "photonlm bake --shard %d/2: exit code %d" % (k, r.returncode))
    r = run([cli, "merge", parts, "-o", merged, "--threads", "1"])
    checks.check(r.returncode == 0 and os.path.isfile(os.path.join(merged, "report.json")),
                 "photonlm merge: exit code %d, report.json written" % r.returncode)
    with open(os.path.join(merged, "report.json")) as f:
        report = json.load(f)
    farm_files = {m["name"]: os.path.join(merged, m["file"]) for m in report["meshes"]}
    checks.check(sorted(farm_files) == sorted(o.name for o in baked_objs),
                 "the report lists the 8 objects: %s" % sorted(farm_files))

    # ---- 2. the in-Blender bake: the truth for wiring and statistics ---------------------------------
    scene.photonlm.output_dir = os.path.join(out, "lightmaps_blender")
    res = bpy.ops.photonlm.bake()
    ref = dict(record.last())  # LAST is cleared by the next bake or import
    ref_rgb = {n: np.array(o["rgb"], np.float32) for n, o in ref["objects"].items()}
    ref_texels = {n: o["texels"] for n, o in ref["objects"].items()}
    ref_stats = dict(ref["stats"])
    ref_wiring = snapshot(baked_objs)
    ref_error = {n: image_rgb(bpy.data.images[n + "_error"]) for n in ref_rgb}
    checks.check(res == {'FINISHED'} and len(ref_rgb) == 8 and ref["csg_objects"] == ["csg_cube"],
                 "the add-on baked 8 lightmaps, the cube as an exact CSG box (%s)" % ref["csg_objects"])
    bpy.ops.photonlm.remove_preview()
    for n in ref_rgb:
        bpy.data.images.remove(bpy.data.images[n + "_lightmap"])
    del scene[record.STATS_KEY]
    from photonlm_blender.writeback import record
    from photonlm_blender.writeback import wiring
    checks.check(not any(wiring.is_wired(m) for m in bpy.data.materials)
                 and not any(n + "_lightmap" in bpy.data.images for n in ref_rgb),
                 "the preview nodes and lightmap images are gone before the import")

    # ---- 3. the import ----------------------------------------------------------------------------
    scene.photonlm.output_dir = os.path.join(out, "lightmaps_import")
    res, msg = import_folder(merged)
    last = record.last()
    checks.check(res == {'FINISHED'} and sorted(last.get("objects", {})) == sorted(ref_rgb),
                 "the import operator brought in the 8 lightmaps (%s %s)" % (res, msg))
    not_equal, unlinked = [], []
    for name, path in farm_files.items():
        image = bpy.data.images.get(name + "_lightmap")
        exr = photonlm.read_lightmap_exr(path).rgb
        if image is None or not np.array_equal(image_rgb(image), exr):
            not_equal.append(name)
        dest = last["objects"][name]["path"]
        if not (dest and filecmp.cmp(dest, path, shallow=False) and image is not None
                and image.packed_file is None and os.path.samefile(bpy.path.abspath(image.filepath), dest)
                and os.path.dirname(dest) == os.path.join(out, "lightmaps_import")):
            unlinked.append(name)
    checks.check(not not_equal, "every image holds its EXR bit for bit (differing: %s)" % not_equal)
    checks.check(not unlinked, "every EXR was copied byte for byte into the scene's lightmap folder and the image "
                 "links that copy, unpacked (wrong: %s)" % unlinked)
    got_wiring = snapshot(baked_objs)
    diff = [m for m in ref_wiring if ref_wiring[m] != got_wiring.get(m)]
    for m in diff[:1]:
        print("in-Blender bake:", ref_wiring[m], "\nimport:", got_wiring.get(m), flush=True)
    checks.check(not diff and len(ref_wiring) == 8,
                 "the node setups of the 8 materials equal those of the in-Blender bake (differing: %s)" % diff)
    worst, scale = 0.0, 0.0
    for name, rgb in ref_rgb.items():
        worst = max(worst, float(np.max(np.abs(photonlm.read_lightmap_exr(farm_files[name]).rgb - rgb))))
        scale = max(scale, float(np.max(rgb)))
    checks.check(scale > 0 and worst <= TOL * scale,
                 "the imported lighting equals the in-Blender bake's: max |diff| %.3g <= %.0e x max texel %.4g"
                 % (worst, TOL, scale))
    heat = max(float(np.max(np.abs(image_rgb(bpy.data.images[n + "_error"]) - ref_error[n]))) for n in ref_error)
    checks.check(heat <= 1e-3, "the heat-map images equal the in-Blender bake's (max |diff| %.3g, half floats)" % heat)
    st = scene.get(record.STATS_KEY) or {}
    rs = report["stats"]
    checks.check(st.get("photons_emitted") == report["photons"]["emitted"] == ref_stats["photons_emitted"]
                 and st.get("error_estimate") == rs["error_estimate"]
                 and abs(st.get("error_estimate", 0) - ref_stats["error_estimate"]) <= 1e-4 * ref_stats["error_estimate"]
                 and st.get("seconds_total") == report["times"]["total"]
                 and st.get("error_p95") == rs["p95"] and st.get("objects") == 8,
                 "the statistics are the report's and the in-Blender bake's: photons %s, error %.6f (Blender %.6f), "
                 "p95 %.4f, engine %.2f s" % (st.get("photons_emitted"), st.get("error_estimate", 0),
                                              ref_stats["error_estimate"], st.get("error_p95", 0),
                                              st.get("seconds_total", 0)))
    p = scene.photonlm
    checks.check(p.last_photons and p.last_error and p.last_time and p.last_objects == "8"
                 and st.get("imported_from") == os.path.normpath(merged) and "seconds_writeback" in st
                 and "seconds_import" in st,
                 "the Last Bake panel shows photons %s, error %s, time %s, objects %s, imported from %s"
                 % (p.last_photons, p.last_error, p.last_time, p.last_objects, st.get("imported_from")))
    from photonlm_blender.operators import import_folder as bake_import
    from photonlm_blender.ui import panel
    from photonlm_blender.writeback import record
    from photonlm_blender.writeback import wiring
    labels = [t for kind, t in drawn(panel.PHOTONLM_PT_last_bake) if kind == "label"]
    times = [t for kind, t in drawn(panel.PHOTONLM_PT_last_times) if kind == "label"]
    checks.check(("operator", "photonlm.import_bake_folder") in drawn(panel.PHOTONLM_PT_output)
                 and bake_import.menu_import in bpy.types.TOPBAR_MT_file_import._dyn_ui_initialize()
                 and any(t.startswith("Imported from") for t in labels) and "Reading Folder" in times
                 and "Write-back" in times,
                 "the Lightmaps sub-panel has the import button, File > Import the entry; Last Bake says where the "
                 "figures came from, Times shows reading the folder (%s)" % [t for t in labels if "Imported" in t])
    counts = {n: (last["objects"][n]["texels"], last["objects"][n]["texels_above"]) for n in ref_texels}
    ref_counts = {n: (ref_texels[n], ref["objects"][n]["texels_above"]) for n in ref_texels}
    checks.check(counts == ref_counts and last["noisiest"] == ref["noisiest"],
                 "per object the covered texels and those above twice the error (the report's) equal the in-Blender "
                 "bake's, and so does the Noisiest hint: %s" % counts)
    # A report without the counts: the texels with photon hits count as covered (hits are recorded only there).
    plain = os.path.join(out, "no_counts")
    shutil.copytree(merged, plain)
    with open(os.path.join(plain, "report.json")) as f:
        doc = json.load(f)
    for m in doc["meshes"]:
        del m["texels"], m["texels_above_twice_target"]
    with open(os.path.join(plain, "report.json"), "w") as f:
        json.dump(doc, f)
    res, msg = import_folder(plain)
    last = record.last()
    wrong = [n for n in ref_texels if last["objects"][n]["texels"] != int(np.count_nonzero(
        (np.asarray(ref["objects"][n]["coverage"]) > 0) & (photonlm.read_lightmap_exr(farm_files[n]).hits > 0)))]
    checks.check(res == {'FINISHED'} and not wrong,
                 "a report without per-mesh counts: the covered texels with photon hits are counted (%s; wrong: %s)"
                 % ({n: (last["objects"][n]["texels"], ref_texels[n]) for n in ref_texels}, wrong))
    import_folder(merged)

    scene.photonlm.pack_lightmaps = True
    res, msg = import_folder(merged)
    packed = [n for n in ref_rgb if bpy.data.images[n + "_lightmap"].packed_file is not None]
    checks.check(res == {'FINISHED'} and len(packed) == 8
                 and np.array_equal(image_rgb(bpy.data.images["floor_lightmap"]),
                                    photonlm.read_lightmap_exr(farm_files["floor"]).rgb),
                 "with Pack the 8 images are packed into the .blend, still bit for bit (%d)" % len(packed))
    scene.photonlm.pack_lightmaps = False

    # ---- 4. orientation lightmaps (a plain photonlm bake: shards refuse OL groups) --------------------
    objs["tall_box"].photonlm.mode = 'ORIENTATION'
    objs["tall_box"].photonlm.ol_resolution = 8
    props = bpy.data.collections.new("props")
    scene.collection.children.link(props)
    props.photonlm.orientation_lightmap = True
    props.photonlm.ol_resolution = 8
    bpy.ops.mesh.primitive_cube_add(size=0.2, location=(-0.6, -0.4, 0.1))
    pebble = bpy.context.active_object
    pebble.name = "pebble"
    pebble.data.materials.append(scenes.diffuse_material("mat_pebble", (0.6, 0.5, 0.4)))
    pebble.photonlm.enabled = False  # geometry only: its light goes into the collection's OL
    for c in list(pebble.users_collection):
        c.objects.unlink(pebble)
    props.objects.link(pebble)
    ol_json = os.path.join(out, "farm_ol", "scene.json")
    bpy.ops.photonlm.export_scene_file(filepath=ol_json)
    ol_out = os.path.join(out, "farm_ol", "out")
    r = run([cli, "bake", ol_json, "-o", ol_out, "--threads", "1"])
    checks.check(r.returncode == 0, "photonlm bake of the scene with two OLs: exit code %d" % r.returncode)
    scene.photonlm.output_dir = os.path.join(out, "lightmaps_blender_ol")
    bpy.ops.photonlm.bake()
    ref_ols = {g: (o["objects"], image_rgb(bpy.data.images[g + "_ol"])) for g, o in record.last()["ols"].items()}
    ref_wiring = snapshot(baked_objs + [pebble])
    bpy.ops.photonlm.remove_preview()
    scene.photonlm.output_dir = os.path.join(out, "lightmaps_import_ol")
    res, msg = import_folder(ol_out)
    with open(os.path.join(ol_out, "report.json")) as f:
        ol_files = {g["name"]: os.path.join(ol_out, g["file"]) for g in json.load(f)["ol_groups"]}
    got = record.last().get("ols", {})
    exact = [g for g, name in (("tall_box", "tall_box"), ("collection_props", "collection props"))
             if g in got and name in ol_files
             and np.array_equal(image_rgb(bpy.data.images[g + "_ol"]), photonlm.read_lightmap_exr(ol_files[name]).rgb)]
    checks.check(res == {'FINISHED'} and sorted(got) == sorted(ref_ols) == ["collection_props", "tall_box"]
                 and all(got[g]["objects"] == ref_ols[g][0] for g in got) and len(exact) == 2,
                 "both OLs (an object's, a collection's) are imported bit for bit, with the bake's objects "
                 "(%s; exact: %s; %s)" % ({g: o["objects"] for g, o in got.items()}, exact, msg))
    worst = max(float(np.max(np.abs(image_rgb(bpy.data.images[g + "_ol"]) - ref_ols[g][1]))) for g in ref_ols)
    scale = max(float(np.max(ref_ols[g][1])) for g in ref_ols)
    checks.check(worst <= TOL * scale, "the imported OLs equal the in-Blender bake's: max |diff| %.3g <= %.0e x %.4g"
                 % (worst, TOL, scale))
    got_wiring = snapshot(baked_objs + [pebble])
    diff = [m for m in ref_wiring if ref_wiring[m] != got_wiring.get(m)]
    groups = [n.node_tree.name for n in pebble.active_material.node_tree.nodes
              if n.bl_idname == 'ShaderNodeGroup' and n.node_tree is not None]
    checks.check(not diff and "PhotonLM OL Lookup" in groups,
                 "the node setups equal the in-Blender bake's, the pebble looks up the collection's OL (differing: %s)"
                 % diff)
    objs["tall_box"].photonlm.mode = 'LIGHTMAP'
    bpy.data.objects.remove(pebble)
    scene.photonlm.output_dir = os.path.join(out, "lightmaps_import")

    # ---- 5. bad input ---------------------------------------------------------------------------------
    res, msg = import_folder(merged)  # the state every refusal must leave as it is
    before = dict(scene[record.STATS_KEY])
    bad = os.path.join(out, "bad")

    def broken(name, change):
        d = os.path.join(bad, name)
        shutil.copytree(merged, d)
        change(d)
        return d

    def refused(folder, words, what):
        res, msg = import_folder(folder)
        same = dict(scene[record.STATS_KEY]) == before and np.array_equal(
            image_rgb(bpy.data.images["floor_lightmap"]), photonlm.read_lightmap_exr(farm_files["floor"]).rgb)
        checks.check(res == {'CANCELLED'} and all(w in msg for w in words) and same,
                     "%s: refused, nothing changed: %s" % (what, msg.strip()))

    refused(os.path.join(out, "no_such_folder"), ["no_such_folder", "is not a folder"], "a missing folder")
    os.makedirs(os.path.join(bad, "empty"))
    refused(os.path.join(bad, "empty"), ["no report.json", "empty"], "a folder without report.json")
    refused(parts, ["shard part files", "part-00001-of-00002.plmpart", "photonlm merge"], "a folder of shard parts")
    slurm = os.path.join(bad, "slurm_out")
    shutil.copytree(parts, os.path.join(slurm, "parts"))
    refused(slurm, ["2 shard part files", "not a merged one", "photonlm merge"],
            "a Slurm output folder whose merge did not run")

    def truncate(d):
        with open(os.path.join(d, "report.json"), "r+") as f:
            f.truncate(100)
    refused(broken("truncated_report", truncate), ["cannot read", "report.json"], "a truncated report.json")

    def other_scene(d):
        with open(os.path.join(d, "report.json")) as f:
            doc = json.load(f)
        for m in doc["meshes"]:
            m["name"] = "other_" + m["name"]
        with open(os.path.join(d, "report.json"), "w") as f:
            json.dump(doc, f)
    refused(broken("other_scene", other_scene), ["none of the 8 objects", "other_csg_cube", "another scene"],
            "a report of another scene")
    floor_file = os.path.basename(farm_files["floor"])
    refused(broken("missing_exr", lambda d: os.remove(os.path.join(d, floor_file))),
            ["lightmap of 'floor' is missing", floor_file], "a missing EXR")

    def garbage(d):
        with open(os.path.join(d, floor_file), "w") as f:
            f.write("not an EXR")
    refused(broken("unreadable_exr", garbage), ["cannot read the lightmap of 'floor'", floor_file],
            "an unreadable EXR")

    def wrong_size(d):
        photonlm.write_lightmap_exr(os.path.join(d, floor_file), np.zeros((8, 8, 3), np.float32))
    refused(broken("wrong_size", wrong_size), ["'floor'", "8 x 8", "16 x 16"], "an EXR of the wrong size")

    objs["floor"].name = "floor_renamed"
    res, msg = import_folder(merged)
    warned = [t for level, t in record.last().get("reports", []) if level == 'WARNING' and "'floor'" in t]
    checks.check(res == {'FINISHED'} and sorted(record.last()["objects"]) == sorted(n for n in ref_rgb if n != "floor")
                 and warned and "not in this .blend" in warned[0],
                 "an object the .blend lacks: warned (%s), the other 7 imported" % (warned[:1],))
    objs["floor"].name = "floor"

    # ---- 6. an atlas: the imported lightmaps go into pages as an in-Blender atlas bake puts them ------
    from photonlm_blender.writeback import atlas
    from photonlm_blender.writeback import record
    from photonlm_blender.writeback import wiring
    scene.photonlm.lightmap_layout = 'ATLAS'
    scene.photonlm.output_dir = os.path.join(out, "atlas_blender")
    bpy.ops.photonlm.bake()
    ref_pages = {os.path.basename(o["path"]) for o in record.last()["objects"].values()}
    ref_pages = {f: photonlm.read_lightmap_exr(os.path.join(out, "atlas_blender", f)) for f in ref_pages}
    ref_wiring = snapshot(baked_objs)
    ref_layout = scene[atlas.LAYOUT_KEY].to_dict()
    bpy.ops.photonlm.remove_preview()
    scene.photonlm.output_dir = os.path.join(out, "atlas_import")
    res, msg = import_folder(merged)
    same = [f for f, lm in ref_pages.items() if all(np.array_equal(a, b) for a, b in zip(
        photonlm.read_lightmap_exr(os.path.join(out, "atlas_import", f))[:3], lm[:3]))]
    ref_layout.pop("files")
    got_layout = scene[atlas.LAYOUT_KEY].to_dict()
    got_layout.pop("files")
    checks.check(res == {'FINISHED'} and len(same) == len(ref_pages) >= 1 and got_layout == ref_layout
                 and snapshot(baked_objs) == ref_wiring,
                 "Layout Atlas: the import packs the same %d page(s) as an in-Blender atlas bake, bit for bit "
                 "(R, G, B, error, hits), the same blocks and node setups (%s)" % (len(ref_pages), msg))
    scene.photonlm.lightmap_layout = 'OBJECT'

    # ---- 7. a saved .blend links the images relative to it --------------------------------------------
    saved = os.path.join(out, "saved", "room.blend")
    os.makedirs(os.path.dirname(saved))
    bpy.ops.wm.save_as_mainfile(filepath=saved)
    scene = bpy.context.scene
    scene.photonlm.output_dir = "//lightmaps/"
    res, msg = import_folder(merged)
    paths = {bpy.data.images[n + "_lightmap"].filepath for n in ref_rgb}
    checks.check(res == {'FINISHED'} and paths == {"//lightmaps/%s_lightmap.exr" % n for n in ref_rgb}
                 and all(os.path.isfile(os.path.join(out, "saved", "lightmaps", n + "_lightmap.exr")) for n in ref_rgb),
                 "in a saved .blend the images link their copies relative to it: %s" % sorted(paths)[:2])
    checks.finish()


main()
