"""Add-on behaviour in headless Blender (no Cycles reference needed).

Checks: register/unregister twice; the automatic 'lightmap' UV map leaves the other UV maps
(names, data) and the active / active-render UV maps untouched; material links intact;
preview on/off switches outputs and off restores the original output exactly; re-baking
does not duplicate nodes; a NaN mesh is reported and skipped while the others bake; images
<object>_lightmap exist, are float Non-Color and match the engine's lightmap and the EXR on
disk (channels R, G, B, error, hits); cancelling through the progress callback leaves earlier
images, files and meshes untouched; file names are sanitised; errors are reported, not raised
as crashes.
"""
import math
import os
import struct
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

PHOTONS = 300_000


def uv_state(mesh):
    data = {}
    for layer in mesh.uv_layers:
        a = np.empty(len(mesh.loops) * 2, np.float32)
        layer.data.foreach_get("uv", a)
        data[layer.name] = a
    active = mesh.uv_layers.active.name if mesh.uv_layers.active else None
    render = [l.name for l in mesh.uv_layers if l.active_render]
    return data, active, render


def tree_state(mat):
    """Original (untagged) nodes, their links, active flags and input default values."""
    nt = mat.node_tree
    nodes = {}
    for n in nt.nodes:
        if n.get("photonlm") is not None:
            continue
        vals = []
        for s in n.inputs:
            v = getattr(s, "default_value", None)
            try:
                v = tuple(v)
            except TypeError:
                pass
            vals.append((s.identifier, v))
        nodes[n.name] = (n.bl_idname, getattr(n, "is_active_output", None), getattr(n, "target", None),
                         tuple(vals))
    links = {(l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier)
             for l in nt.links if l.from_node.get("photonlm") is None and l.to_node.get("photonlm") is None}
    return nodes, links


def exr_channels(path):
    """Channel names from an OpenEXR header (the 'channels' chlist attribute)."""
    with open(path, "rb") as f:
        data = f.read(1 << 16)
    assert data[:4] == b"\x76\x2f\x31\x01", "not an OpenEXR file"
    pos = 8
    while pos < len(data) and data[pos] != 0:
        name_end = data.index(b"\0", pos)
        name = data[pos:name_end].decode()
        type_end = data.index(b"\0", name_end + 1)
        atype = data[name_end + 1:type_end].decode()
        (size,) = struct.unpack("<i", data[type_end + 1:type_end + 5])
        value = data[type_end + 5:type_end + 5 + size]
        if name == "channels" and atype == "chlist":
            names, p = [], 0
            while value[p] != 0:
                e = value.index(b"\0", p)
                names.append(value[p:e].decode())
                p = e + 1 + 16
            return names
        pos = type_end + 5 + size
    return []


def image_rgb(image):
    w, h = image.size
    px = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    return px.reshape(h, w, 4)[..., :3]


def build_scene():
    scenes.clear_scene()
    # A cube (Blender's own UVs) with a second UV map, a textured Principled material with emission.
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0, 0, 0.5))
    cube = bpy.context.object
    cube.name = "cube"
    me = cube.data
    second = me.uv_layers.new(name="Texture2")
    a = np.linspace(0, 1, len(me.loops) * 2, dtype=np.float32)
    second.data.foreach_set("uv", a)
    me.uv_layers.active = me.uv_layers["Texture2"]      # edited map: Texture2
    me.uv_layers["UVMap"].active_render = True          # rendered map: UVMap
    mat = scenes.node_material("cube_mat")
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    tex = nt.nodes.new("ShaderNodeTexChecker")
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    scenes.principled_input(bsdf, "Emission").default_value = (0.2, 0.1, 0.0, 1.0)
    bsdf.inputs["Emission Strength"].default_value = 2.0
    me.materials.append(mat)
    # A floor with a fixed lightmap layout and its own material.
    floor = scenes.plane("floor", scenes.diffuse_material("floor_mat", (0.7, 0.7, 0.7)), size=6.0, resolution=32)
    # Two objects sharing one material.
    shared = scenes.diffuse_material("shared_mat", (0.5, 0.6, 0.7))
    s1 = scenes.quads_object("shared_a", [((2, -1, 0.5), (2.5, -1, 0.5), (2.5, -0.5, 0.5), (2, -0.5, 0.5),
                                           (0, 0, 1, 1))], shared, 16)
    s2 = scenes.quads_object("shared_b", [((2, 1, 0.5), (2.5, 1, 0.5), (2.5, 1.5, 0.5), (2, 1.5, 0.5),
                                           (0, 0, 1, 1))], shared, 16)
    # A broken mesh: one NaN vertex.
    broken = scenes.quads_object("broken", [((-2, -2, 1), (-1.5, -2, 1), (-1.5, -1.5, 1), (-2, -1.5, 1),
                                             (0, 0, 1, 1))], scenes.diffuse_material("broken_mat", (0.5,) * 3), 16)
    broken.data.vertices[0].co = (float("nan"), -2.0, 1.0)
    # An awkward name.
    odd = scenes.quads_object("odd/name:*?", [((-2, 2, 0.3), (-1.5, 2, 0.3), (-1.5, 2.5, 0.3), (-2, 2.5, 0.3),
                                               (0, 0, 1, 1))], scenes.diffuse_material("odd_mat", (0.5,) * 3), 16)
    scenes.add_light("sun", 'SUN', (0, 0, 5), rotation=(math.radians(20), math.radians(10), 0), energy=3.0)
    scenes.add_light("lamp", 'POINT', (1.0, -1.0, 2.0), energy=200.0)
    scenes.set_world_color((0.05, 0.05, 0.08))
    # Cycles portals: a rectangle is exported as a portal, a disk is reported and skipped.
    window = scenes.add_light("window", 'AREA', (0, 0, 3), shape='RECTANGLE', size=2.0, size_y=1.0)
    window.data.cycles.is_portal = True
    round_window = scenes.add_light("round_window", 'AREA', (0, 0, 3.5), shape='DISK', size=1.0)
    round_window.data.cycles.is_portal = True
    return dict(cube=cube, floor=floor, shared_a=s1, shared_b=s2, broken=broken, odd=odd)


def main():
    plm = scenes.setup_paths()
    checks = scenes.Checks("addon_behaviour")
    from photonlm_blender.bake import job as bake
    from photonlm_blender.writeback import wiring
    from photonlm_blender.export import meshes

    # -- register / unregister twice --------------------------------------------------------------
    ok = True
    try:
        for _ in range(2):
            plm.unregister()
            ok &= not hasattr(bpy.types.Scene, "photonlm") and not hasattr(bpy.types, "PHOTONLM_OT_bake")
            plm.register()
            ok &= hasattr(bpy.types.Scene, "photonlm") and hasattr(bpy.types.Object, "photonlm")
    except Exception as e:  # noqa: BLE001
        ok = False
        print("register/unregister raised:", e)
    checks.check(ok, "register() / unregister() twice without errors")
    checks.check(bpy.types.Scene.bl_rna.properties.get("photonlm") is not None
                 and getattr(bpy.types, "PHOTONLM_PT_lightmaps", None) is not None, "settings and panel registered")
    sp = bpy.context.scene.photonlm
    checks.check(sp.photons == 50_000_000 and abs(sp.target_error - 0.02) < 1e-9 and sp.time_budget == 0.0
                 and sp.direct_samples == 64 and sp.texel_density == 32 and sp.output_dir == "//lightmaps/",
                 "defaults: target error 2%, no time budget, at most 50,000,000 photons, 64 direct samples, "
                 "32 texels/m, //lightmaps/")

    # -- nothing to bake: a reported error, not a crash -----------------------------------------------
    scenes.clear_scene()
    try:
        r = bpy.ops.photonlm.bake()
        checks.check(r == {'CANCELLED'}, "empty scene: bake cancelled (%s)" % r)
    except RuntimeError as e:
        checks.check("nothing to bake" in str(e), "empty scene: error reported: %s" % str(e).strip())

    objs = build_scene()
    cube = objs["cube"]
    uv_before = uv_state(cube.data)
    mats = {m.name: tree_state(m) for m in bpy.data.materials}
    sel_before = [o.name for o in bpy.context.view_layer.objects if o.select_get()]
    active_before = bpy.context.view_layer.objects.active

    last = scenes.photonlm_bake(PHOTONS, 8, seed=2)
    reports = [t for (_, t) in last["reports"]]
    print("reports:\n  " + "\n  ".join(reports))

    # -- Reached error and time, readable by scripts ---------------------------------------------------
    stored = bpy.context.scene.get("photonlm_last_bake", {})
    err = float(stored.get("error_estimate", -1.0))
    checks.check(0.0 < err < 1.0 and abs(err - last["stats"]["error_estimate"]) < 1e-12
                 and bpy.context.scene.photonlm.last_error == "%.2f %%" % (100 * err)
                 and float(stored.get("seconds_total", 0)) > 0.0,
                 "reached error (%s) and time (%s) readable from the scene after the bake"
                 % (bpy.context.scene.photonlm.last_error, bpy.context.scene.photonlm.last_time))

    # -- UV maps ---------------------------------------------------------------------------------------
    data, active, render = uv_state(cube.data)
    checks.check("lightmap" in data, "cube got a 'lightmap' UV map")
    checks.check(all(n in data and np.array_equal(data[n], v) for n, v in uv_before[0].items()),
                 "other UV maps untouched (names %s, data identical)" % sorted(uv_before[0]))
    checks.check(active == uv_before[1] and render == uv_before[2],
                 "active UV map '%s' and render UV map %s unchanged (now '%s', %s)"
                 % (uv_before[1], uv_before[2], active, render))
    lm = data.get("lightmap")
    checks.check(lm is not None and lm.min() >= 0.0 and lm.max() <= 1.0 and np.ptp(lm) > 0.5,
                 "lightmap UVs inside [0, 1]")
    checks.check([o.name for o in bpy.context.view_layer.objects if o.select_get()] == sel_before
                 and bpy.context.view_layer.objects.active == active_before and cube.mode == 'OBJECT',
                 "selection, active object and mode unchanged by the UV unwrap")

    # -- broken mesh -------------------------------------------------------------------------------------
    broken_msgs = [t for t in reports if "broken" in t and "skipped" in t]
    checks.check(bool(broken_msgs), "NaN mesh reported and skipped: %s" % (broken_msgs[:1],))
    baked = set(last["objects"])
    checks.check(not any("zero lightmap UV area" in t for t in reports),
                 "no engine warning about zero lightmap UV area (the automatic UV map is really unwrapped)")
    checks.check("broken" not in baked and {"cube", "floor", "shared_a", "shared_b", "odd/name:*?"} <= baked,
                 "other objects baked: %s" % sorted(baked))
    checks.check(any("shared_mat" in t and "shared" in t for t in reports), "shared material reported")
    checks.check(any("portal 'window'" in t and "sampled through it" in t for t in reports)
                 and any("portal 'round_window'" in t and "skipped" in t for t in reports),
                 "rectangular portal exported, disk portal reported and skipped")

    # -- images and EXR files ------------------------------------------------------------------------------
    for name in sorted(baked):
        info = last["objects"][name]
        img = bpy.data.images.get(name + "_lightmap")
        if not checks.check(img is not None, "image '%s_lightmap' exists" % name):
            continue
        rgb = image_rgb(img)
        diff = float(np.abs(rgb - info["rgb"]).max()) if rgb.shape == info["rgb"].shape else float("inf")
        checks.check(diff <= 1e-6 * max(1.0, float(info["rgb"].max())),
                     "%s: image pixels == engine lightmap (rows bottom first), max diff %.3g, %dx%d, mean %.4f"
                     % (name, diff, img.size[0], img.size[1], float(info["rgb"].mean())))
        checks.check(img.is_float and img.colorspace_settings.name == 'Non-Color' and
                     os.path.abspath(bpy.path.abspath(img.filepath)) == os.path.abspath(info["path"]),
                     "%s: float, Non-Color, loaded from %s" % (name, os.path.basename(info["path"])))
        channels = exr_channels(info["path"])
        checks.check(sorted(channels) == sorted(["R", "G", "B", "error", "hits"]),
                     "%s: EXR channels %s" % (name, channels))
        # An independent load of the file on disk equals the image.
        fresh = bpy.data.images.load(info["path"], check_existing=False)
        fresh.colorspace_settings.name = 'Non-Color'
        same = np.array_equal(image_rgb(fresh), rgb)
        bpy.data.images.remove(fresh)
        checks.check(same, "%s: image == EXR on disk" % name)
    odd_path = last["objects"].get("odd/name:*?", {}).get("path", "")
    checks.check(os.path.basename(odd_path) == "odd_name_lightmap.exr", "file name sanitised: %s"
                 % os.path.basename(odd_path))

    # -- materials ----------------------------------------------------------------------------------------------
    def links_intact():
        return all(tree_state(m)[1] == mats[m.name][1] for m in bpy.data.materials if m.name in mats)

    def nodes_intact():
        bad = [m.name for m in bpy.data.materials if m.name in mats and tree_state(m)[0] != mats[m.name][0]]
        return not bad, bad

    checks.check(links_intact(), "original material links intact after baking")
    ok, bad = nodes_intact()
    checks.check(ok, "original nodes and active outputs unchanged with the preview off %s" % bad)
    cube_mat = bpy.data.materials["cube_mat"]
    nt = cube_mat.node_tree
    tagged = [n for n in nt.nodes if n.get("photonlm") is not None]
    ours_out = next((n for n in tagged if n.get("photonlm") == "output"), None)
    checks.check(ours_out is not None and len(tagged) >= 7, "preview nodes added (%d tagged)" % len(tagged))
    mul = next(n for n in tagged if n.get("photonlm") == "multiply")
    checks.check(mul.inputs["Color1"].is_linked and mul.inputs["Color1"].links[0].from_node.bl_idname == 'ShaderNodeTexChecker',
                 "preview multiplies by the linked base colour (same source socket)")
    tex = next(n for n in tagged if n.get("photonlm") == "image")
    checks.check(tex.image is not None and tex.image.name == "cube_lightmap", "preview image is cube_lightmap")
    uvn = next(n for n in tagged if n.get("photonlm") == "uv")
    checks.check(uvn.uv_map == "lightmap", "preview UV Map node uses 'lightmap'")

    scene = bpy.context.scene
    scene.photonlm.preview = True
    on = all(m.node_tree.get_output_node(t).get("photonlm") == "output"
             for m in bpy.data.materials if wiring.is_wired(m) for t in ('CYCLES', 'EEVEE'))
    checks.check(on, "preview on: every wired material renders through the PhotonLM output")
    checks.check(links_intact(), "original links intact with the preview on")
    scene.photonlm.preview = False
    ok, bad = nodes_intact()
    checks.check(ok and links_intact(), "preview off: original outputs, nodes and links restored exactly %s" % bad)
    checks.check(nt.get_output_node('CYCLES').get("photonlm") is None, "preview off: original output active")

    # -- re-bake: no duplicated nodes; preview state kept ----------------------------------------------------------------
    counts = {m.name: len(m.node_tree.nodes) for m in bpy.data.materials if m.node_tree}
    scene.photonlm.preview = True
    last2 = scenes.photonlm_bake(PHOTONS, 8, seed=3)
    counts2 = {m.name: len(m.node_tree.nodes) for m in bpy.data.materials if m.node_tree}
    checks.check(counts == counts2, "re-bake reuses the preview nodes (node counts %s)" % counts2)
    checks.check(nt.get_output_node('CYCLES').get("photonlm") == "output", "re-bake with preview on keeps it on")
    img = bpy.data.images["cube_lightmap"]
    checks.check(np.array_equal(image_rgb(img), last2["objects"]["cube"]["rgb"]),
                 "re-bake reloads the existing image (seed 3 result shown)")
    checks.check(len([i for i in bpy.data.images if i.name.startswith("cube_lightmap")]) == 1,
                 "no duplicate images")
    scene.photonlm.preview = False

    # -- cancellation ---------------------------------------------------------------------------------------------------
    newobj = scenes.quads_object("late", [((3, 3, 0), (3.5, 3, 0), (3.5, 3.5, 0), (3, 3.5, 0), (0, 0, 1, 1))],
                                 scenes.diffuse_material("late_mat", (0.5,) * 3), 16)
    newobj.data.uv_layers.remove(newobj.data.uv_layers["lightmap"])  # will get an automatic one
    late_uvs = sorted(newobj.data.uv_layers.keys())
    files = {n: (os.path.getmtime(o["path"]), open(o["path"], "rb").read()) for n, o in last2["objects"].items()}
    pixels = {n: image_rgb(bpy.data.images[n + "_lightmap"]).copy() for n in last2["objects"]}
    stats_before = dict(scene.get("photonlm_last_bake", {}))
    calls = []

    def cancel_soon(fraction, stage):
        calls.append((fraction, stage))
        return len(calls) < 2

    scene.photonlm.photons = 50_000_000
    job = bake.BakeJob(bpy.context)
    checks.check("lightmap" in newobj.data.uv_layers, "job preparation created the missing UV map")
    job.run(progress=cancel_soon)
    checks.check(job.cancelled and job.result is None, "progress callback returning False cancels (%d calls, "
                 "last %s)" % (len(calls), calls[-1] if calls else None))
    job.abort(bpy.context)
    checks.check(sorted(newobj.data.uv_layers.keys()) == late_uvs, "cancel removes the UV map it created")
    same_files = all(os.path.getmtime(o["path"]) == files[n][0] and open(o["path"], "rb").read() == files[n][1]
                     for n, o in last2["objects"].items())
    same_pixels = all(np.array_equal(image_rgb(bpy.data.images[n + "_lightmap"]), p) for n, p in pixels.items())
    checks.check(same_files and same_pixels, "cancel leaves earlier EXR files and images untouched")
    checks.check(dict(scene.get("photonlm_last_bake", {})) == stats_before, "cancel leaves the statistics")
    checks.check(bpy.data.images.get("late_lightmap") is None, "cancel creates no image")

    # -- 'INVOKE_DEFAULT' without a window (blender -b) runs the synchronous bake ------------------------------
    scene.photonlm.photons = PHOTONS
    r = bpy.ops.photonlm.bake('INVOKE_DEFAULT')
    checks.check(r == {'FINISHED'} and bpy.data.images.get("late_lightmap") is not None,
                 "invoke without a window bakes synchronously (%s)" % r)

    # -- export: modifiers applied, world-space positions --------------------------------------------------------------
    from photonlm_blender.writeback import wiring
    from photonlm_blender.export import meshes
    cube.location = (0.3, -0.2, 0.7)
    cube.rotation_euler = (0.3, 0.2, 0.1)
    cube.scale = (1.0, 2.0, 0.5)
    cube.modifiers.new("subsurf", 'SUBSURF').levels = 1
    bpy.context.view_layer.update()
    dg = bpy.context.evaluated_depsgraph_get()
    with meshes.evaluated_mesh(cube, dg) as (cube_eval, mesh):
        pos, tris, _, uv = meshes.mesh_arrays(mesh, cube_eval.matrix_world, True)
        mw = np.array(cube_eval.matrix_world)
        local = np.array([v.co[:] for v in mesh.vertices])
    want = local @ mw[:3, :3].T + mw[:3, 3]
    checks.check(len(tris) == 48 and uv is not None and uv.shape == (48, 3, 2),
                 "export applies modifiers (subdivided cube: %d triangles, lightmap UVs %s)"
                 % (len(tris), None if uv is None else uv.shape))
    checks.check(np.allclose(pos, want, atol=1e-5), "export positions are in world space (matrix_world applied)")

    # -- statistics strings ------------------------------------------------------------------------------------------------
    s = scene.photonlm
    checks.check(s.last_photons == "{:,}".format(PHOTONS) and s.last_time.endswith(" s") and "photons/s" in s.last_rate,
                 "statistics: %s photons, %s, %s, %s warnings" % (s.last_photons, s.last_time, s.last_rate,
                                                                  s.last_warnings))
    checks.finish()


main()
