"""Lightmap atlases: 52 small objects (cubes and ico spheres of five sizes, two of them linked
duplicates) and a floor under a sun,
baked into 512 x 512 atlas pages at one texel density, then compared with a lightmap-per-object bake
of the same scene (same seed, each object at its atlas block's size).

Expected:
- pages: as many as the cells' area needs (ceil(sum of (w + 2 pad)(h + 2 pad) / 512^2)) or one more,
  and few (at most 4); every object's block size is ceil(sqrt(area) x density x density scale)
  (the floor's density scale 0.25 shows in its block);
- no two cells (block + pad) overlap, none leaves its page; every object's 'PhotonLM Atlas' UVs lie
  inside its block; the page file holds each object's baked texels at its block, bit for bit, and
  the block's edge texels in the pad around it;
- each object's light read through 'PhotonLM Atlas' from its page (bilinear, at points spread over
  every triangle) matches its own lightmap read through 'lightmap' in the per-object bake: per-object
  mean and RMS within 1 % (the two bakes see the same engine input, so they agree to rounding);
  read with a wrong place (another object's block, or its own moved by half a block) at least 90 %
  of the objects do not (a few objects' light may happen to match another's);
- the preview reads the page through 'PhotonLM Atlas'; Remove Preview removes its nodes; a bake
  into lightmaps of their own removes the objects' atlas UV map and properties;
- a glTF export (modifiers applied) of an object holds its atlas UVs as TEXCOORD_<index of the map>,
  inside its block, spanning what the evaluated mesh's map spans;
- Bake Selected (another seed): blocks keep their size and place, texels outside the selected
  objects' cells are unchanged bit for bit, inside they are new; a selected object whose block
  grows (density scale 2) moves to free space and nothing else moves; Bake Selected after the
  page size changed, and a Resolution too large for a page, are refused naming why; an object whose
  density asks for more than a page is capped to fit, with a warning naming it;
- one object has an Array modifier (its automatic map in a helper mesh, carried by Data Transfer),
  one a Subdivision Surface the engine refines from the cage, and the first and another object
  have linked duplicates (one mesh, one helper for two blocks): all are
  checked like the others.
"""
import json
import math
import os
import shutil
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

PAGE = 512
DENSITY = 96
ATLAS_UV = "PhotonLM Atlas"
SIZES = (("cube", 0.2), ("cube", 0.35), ("cube", 0.5), ("ico", 0.15), ("ico", 0.3))


def build():
    scenes.clear_scene()
    bpy.ops.mesh.primitive_plane_add(size=10.0, location=(0, 0, 0))
    floor = bpy.context.active_object
    floor.name = "floor"
    floor.data.materials.append(scenes.diffuse_material("floor", (0.6, 0.6, 0.6)))
    floor.photonlm.density_scale = 0.25
    for i in range(50):
        kind, s = SIZES[i % len(SIZES)]
        x, y = -4.2 + 0.95 * (i % 10), -4.0 + 1.8 * (i // 10) + 0.3 * (i % 2)
        if kind == "cube":
            bpy.ops.mesh.primitive_cube_add(size=s, location=(x, y, s / 2))
        else:
            bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2, radius=s, location=(x, y, s))
        obj = bpy.context.active_object
        obj.name = "obj_%02d" % i
        if i == 5:  # a modifier that changes the topology: the automatic map lives in a helper mesh
            obj.modifiers.new("Array", 'ARRAY').count = 2
        if i == 6:  # refined by the engine from its cage: the atlas warp goes before the subdivision
            sub = obj.modifiers.new("Subdivision", 'SUBSURF')
            sub.levels = sub.render_levels = 1
        obj.data.materials.append(scenes.diffuse_material("mat_%02d" % i, (0.3 + 0.01 * i, 0.5, 0.7)))
    for src, name, y in (("obj_05", "obj_05_twin", 4.6), ("obj_02", "obj_02_twin", 4.6)):
        # Linked duplicates: one mesh (and for obj_05 one helper mesh) for two objects in two blocks.
        twin = bpy.data.objects[src].copy()
        twin.name = name
        twin.location.y = y
        bpy.context.scene.collection.objects.link(twin)
    scenes.add_light("sun", 'SUN', (0, 0, 5), rotation=(0.5, 0.3, 0.0), energy=3.0)
    scenes.set_world_color((0.05, 0.05, 0.05))
    s = bpy.context.scene.photonlm
    s.texel_density = DENSITY
    s.lightmap_layout = 'ATLAS'
    s.atlas_size = str(PAGE)
    s.lightmap_margin = 8
    s.direct_samples = 8


def surface_area(obj):
    deps = bpy.context.evaluated_depsgraph_get()
    mesh = obj.evaluated_get(deps).to_mesh()
    mw = np.array(obj.matrix_world)
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3) @ mw[:3, :3].T
    mesh.calc_loop_triangles()
    tri = np.empty(len(mesh.loop_triangles) * 3, np.int32)
    mesh.loop_triangles.foreach_get("vertices", tri)
    a, b, c = (co[tri.reshape(-1, 3)[:, k]] for k in range(3))
    obj.evaluated_get(deps).to_mesh_clear()
    return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())


BARY = np.array([[1 / 3, 1 / 3, 1 / 3], [0.6, 0.2, 0.2], [0.2, 0.6, 0.2], [0.2, 0.2, 0.6],
                 [0.45, 0.45, 0.1], [0.1, 0.45, 0.45], [0.45, 0.1, 0.45]])


def surface_uvs(obj, maps=("lightmap", ATLAS_UV)):
    """The UVs of `maps` at points spread over every triangle of the evaluated mesh: (N, 2) each."""
    deps = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(deps)
    mesh = ev.to_mesh()
    try:
        mesh.calc_loop_triangles()
        loops = np.empty(len(mesh.loop_triangles) * 3, np.int32)
        mesh.loop_triangles.foreach_get("loops", loops)
        out = []
        for name in maps:
            uv = np.empty(len(mesh.loops) * 2, np.float32)
            mesh.uv_layers[name].data.foreach_get("uv", uv)
            corners = uv.reshape(-1, 2)[loops].reshape(-1, 3, 2).astype(np.float64)
            out.append(np.einsum("pk,tkc->tpc", BARY, corners).reshape(-1, 2))
        return out
    finally:
        ev.to_mesh_clear()


def corner_uv_names(obj):
    ev = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = ev.to_mesh()
    names = list(mesh.uv_layers.keys())
    ev.to_mesh_clear()
    return names


def corner_uvs(obj):
    """The evaluated mesh's atlas UVs at every face corner, (N, 2)."""
    ev = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = ev.to_mesh()
    try:
        uv = np.empty(len(mesh.loops) * 2, np.float32)
        mesh.uv_layers[ATLAS_UV].data.foreach_get("uv", uv)
        return uv.reshape(-1, 2)
    finally:
        ev.to_mesh_clear()


def gltf_atlas_uvs(obj, folder):
    """Export obj alone as glTF (modifiers applied) and read back its 'PhotonLM Atlas' UVs, the
    TEXCOORD_<index of the map>, in Blender's orientation (v = 1 - glTF's v). None if absent."""
    os.makedirs(folder, exist_ok=True)
    for o in bpy.context.view_layer.objects:
        o.select_set(o == obj)
    path = os.path.join(folder, obj.name + ".gltf")
    bpy.ops.export_scene.gltf(filepath=path, export_format='GLTF_SEPARATE', use_selection=True,
                              export_apply=True, export_materials='NONE')
    with open(path) as f:
        doc = json.load(f)
    with open(os.path.join(folder, doc["buffers"][0]["uri"]), "rb") as f:
        data = f.read()
    key = "TEXCOORD_%d" % list(obj.data.uv_layers.keys()).index(ATLAS_UV)
    out = []
    for prim in doc["meshes"][0]["primitives"]:
        if key not in prim["attributes"]:
            return None
        acc = doc["accessors"][prim["attributes"][key]]
        view = doc["bufferViews"][acc["bufferView"]]
        assert view.get("byteStride", 8) == 8 and acc["componentType"] == 5126
        start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        out.append(np.frombuffer(data, np.float32, count=2 * acc["count"], offset=start).reshape(-1, 2))
    uv = np.concatenate(out).astype(np.float64)
    uv[:, 1] = 1.0 - uv[:, 1]
    return uv


def bilinear(image, uv):
    """Bilinear lookup of image (h, w, 3), row 0 at v = 0, edge texels repeated beyond the border."""
    h, w = image.shape[:2]
    x = uv[:, 0] * w - 0.5
    y = uv[:, 1] * h - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]

    def at(yy, xx):
        return image[np.clip(yy, 0, h - 1), np.clip(xx, 0, w - 1)]
    return ((1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x0 + 1))
            + fy * ((1 - fx) * at(y0 + 1, x0) + fx * at(y0 + 1, x0 + 1)))


def mean_rms(values):
    lum = values.mean(axis=1)
    return float(lum.mean()), float(np.sqrt((lum ** 2).mean()))


def close(a, b, tol=0.01):
    return abs(a[0] - b[0]) <= tol * abs(b[0]) and abs(a[1] - b[1]) <= tol * abs(b[1])


def bake_selected(names, seed):
    for o in bpy.context.view_layer.objects:
        o.select_set(o.name in names)
    bpy.context.scene.photonlm.seed = seed
    try:
        return bpy.ops.photonlm.bake(selected_only=True)
    except RuntimeError as e:  # a background operator's error report raises
        return str(e)


def main():
    checks = scenes.Checks("atlas")
    scenes.setup_paths()
    import photonlm
    from photonlm_blender.writeback import atlas
    from photonlm_blender.uv import atlas_pack
    from photonlm_blender.export import materials
    from photonlm_blender.writeback import wiring
    from photonlm_blender.uv import uvmaps
    build()
    out = scenes.out_dir("atlas")
    bpy.context.scene.photonlm.output_dir = out
    shutil.rmtree(out)
    os.makedirs(out)
    last = scenes.photonlm_bake(400_000, 4, seed=5, target_error=0.0)
    layout = bpy.context.scene[atlas.LAYOUT_KEY].to_dict()
    names = sorted(last["objects"])
    pad = layout["pad"]
    places = {n: atlas_pack.Placement(*layout["blocks"][n]) for n in names}
    from photonlm_blender.uv import uvmaps
    from photonlm_blender.writeback import wiring
    mods6 = [m.type for m in bpy.data.objects["obj_06"].modifiers]
    checks.check(mods6 == ['UV_WARP', 'SUBSURF'], "obj_06's atlas warp comes before its subdivision: %s" % mods6)
    twins = [bpy.data.objects[n] for n in ("obj_05", "obj_05_twin")]
    mods = [uvmaps.automatic_modifier(o) for o in twins]
    checks.check(len(names) == 53 and pad == 4 and None not in mods and mods[0].object == mods[1].object
                 and bpy.data.objects["obj_02"].data == bpy.data.objects["obj_02_twin"].data,
                 "53 objects baked into the atlas, pad %d (margin 8); obj_05 and its twin share a helper mesh, "
                 "obj_02 and its twin a mesh" % pad)

    # -- pages: few, as the area needs ------------------------------------------------------------
    cells = sum((p.w + 2 * pad) * (p.h + 2 * pad) for p in places.values())
    lower = math.ceil(cells / PAGE ** 2)
    pages = len(layout["pages"])
    fill = [sum((p.w + 2 * pad) * (p.h + 2 * pad) for p in places.values() if p.page == k) / PAGE ** 2
            for k in range(pages)]
    checks.check(lower <= pages <= min(lower + 1, 4),
                 "%d pages for %d cell texels (%.2f pages' worth; pages filled %s)"
                 % (pages, cells, cells / PAGE ** 2, ", ".join("%.0f %%" % (100 * f) for f in fill)))
    files = sorted(f for f in os.listdir(out) if f.endswith("_lightmap.exr"))
    checks.check(files == sorted("Scene_atlas_%d_lightmap.exr" % k for k in range(pages)),
                 "one EXR per page and no per-object files: %s" % files)
    wrong = []
    for n in names:
        obj = bpy.data.objects[n]
        if n == "obj_06":
            continue  # sized from its cage's area, as in lightmaps of their own (subdiv_export.py)
        want = max(16, math.ceil(math.sqrt(surface_area(obj)) * DENSITY * obj.photonlm.density_scale))
        if (places[n].w, places[n].h) != (want, want):
            wrong.append("%s %s != %d" % (n, places[n][3:], want))
    checks.check(not wrong and places["floor"].w == 240,
                 "blocks are ceil(sqrt(area) x density x scale) texels (floor %d): %s" % (places["floor"].w, wrong[:3]))

    # -- blocks: no overlap, texels in place ------------------------------------------------------
    pairs, outside = atlas_pack.overlapping([places[n] for n in names], pad, PAGE)
    checks.check(not pairs and not outside, "no cells overlap (%d pairs) or leave the page (%d)"
                 % (len(pairs), len(outside)))
    page_data = [photonlm.read_lightmap_exr(os.path.join(out, "Scene_atlas_%d_lightmap.exr" % k))
                 for k in range(pages)]
    misplaced, uv_outside = [], []
    for n in names:
        p = places[n]
        cell = page_data[p.page].rgb[p.y - pad:p.y + p.h + pad, p.x - pad:p.x + p.w + pad]
        if not np.array_equal(cell, np.pad(last["objects"][n]["rgb"], ((pad, pad), (pad, pad), (0, 0)), "edge")):
            misplaced.append(n)
        _, auv = surface_uvs(bpy.data.objects[n])
        lo, hi = np.array([p.x, p.y]) / PAGE, np.array([p.x + p.w, p.y + p.h]) / PAGE
        if not ((auv >= lo - 1e-6).all() and (auv <= hi + 1e-6).all()):
            uv_outside.append(n)
        so = tuple(bpy.data.objects[n][atlas.SCALE_OFFSET_KEY])
        if not np.allclose(so, p.scale_offset(PAGE)):
            uv_outside.append(n + " (scale-offset)")
    checks.check(not misplaced, "the page holds every object's texels at its block, its edge texels repeated in "
                 "the margin around it: wrong for %s" % misplaced[:5])
    checks.check(not uv_outside, "every object's atlas UVs lie inside its block: not for %s" % uv_outside[:5])

    # -- the preview reads the page through the atlas UV map ----------------------------------------
    mat = bpy.data.materials["mat_07"]
    uv_node = next(n for n in mat.node_tree.nodes if n.get(materials.TAG) == "uv")
    tex = next(n for n in mat.node_tree.nodes if n.get(materials.TAG) == "image")
    page_image = bpy.data.objects["obj_07"][atlas.PAGE_KEY]
    checks.check(uv_node.uv_map == ATLAS_UV and tex.image.name == page_image and page_image.startswith("Scene_atlas_"),
                 "the preview reads '%s' through '%s'" % (tex.image.name, uv_node.uv_map))

    # -- a glTF export (modifiers applied) carries the atlas UV map -----------------------------------
    for n in ("obj_05", "obj_05_twin", "obj_07", "obj_02_twin"):
        got = gltf_atlas_uvs(bpy.data.objects[n], os.path.join(out, "gltf"))
        p = places[n]
        lo, hi = np.array([p.x, p.y]) / PAGE, np.array([p.x + p.w, p.y + p.h]) / PAGE
        corners = corner_uvs(bpy.data.objects[n])
        checks.check(got is not None and (got >= lo - 1e-6).all() and (got <= hi + 1e-6).all()
                     and np.allclose(got.min(axis=0), corners.min(axis=0), atol=1e-6)
                     and np.allclose(got.max(axis=0), corners.max(axis=0), atol=1e-6),
                     "the glTF export of %s holds its atlas UVs as TEXCOORD_%d, inside its block"
                     % (n, list(bpy.data.objects[n].data.uv_layers.keys()).index(ATLAS_UV)))

    # -- the per-object bake of the same scene, through the atlas and through its own map ------------
    atlas_uvs = {n: surface_uvs(bpy.data.objects[n])[1] for n in names}
    for n in names:
        bpy.data.objects[n].photonlm.resolution = places[n].w
    bpy.context.scene.photonlm.lightmap_layout = 'OBJECT'
    ref = scenes.photonlm_bake(400_000, 4, seed=5, target_error=0.0)
    stale = [n for n in names if atlas.PAGE_KEY in bpy.data.objects[n] or ATLAS_UV in bpy.data.objects[n].data.uv_layers
             or ATLAS_UV in corner_uv_names(bpy.data.objects[n])]
    checks.check(not stale, "baked into lightmaps of their own, objects lose their atlas UV map and properties: "
                 "not %s" % stale[:3])
    bad, worst = [], 0.0
    wrong_other, wrong_shift = 0, 0
    for i, n in enumerate(names):
        luv, = surface_uvs(bpy.data.objects[n], ("lightmap",))
        own = photonlm.read_lightmap_exr(ref["objects"][n]["path"]).rgb
        want = mean_rms(bilinear(own, luv))
        p = places[n]
        got = mean_rms(bilinear(page_data[p.page].rgb, atlas_uvs[n]))
        worst = max(worst, abs(got[0] / want[0] - 1.0), abs(got[1] / want[1] - 1.0))
        if not close(got, want):
            bad.append("%s %.4g/%.4g vs %.4g/%.4g" % (n, got[0], got[1], want[0], want[1]))
        # The same lookup with a wrong place: another object's block, or its own moved by half a block.
        q = places[names[(i + 7) % len(names)]]
        su, sv, ou, ov = p.scale_offset(PAGE)
        local = (atlas_uvs[n] - [ou, ov]) / [su, sv]
        qs = q.scale_offset(PAGE)
        other = mean_rms(bilinear(page_data[q.page].rgb, local * qs[:2] + qs[2:]))
        shifted = mean_rms(bilinear(page_data[p.page].rgb, atlas_uvs[n] + [0.5 * su, 0.0]))
        wrong_other += not close(other, want)
        wrong_shift += not close(shifted, want)
    checks.check(not bad, "through the atlas UV map every object's light matches its own lightmap (mean and "
                 "RMS within 1 %%, worst %.2g %%): %s" % (100.0 * worst, bad[:3]))
    checks.check(wrong_other >= 0.9 * len(names) and wrong_shift >= 0.9 * len(names),
                 "the comparison fails with a wrong place: another block for %d / %d objects, half a block "
                 "off for %d" % (wrong_other, len(names), wrong_shift))

    # -- back to the atlas; Bake Selected keeps the layout ---------------------------------------------
    for n in names:
        bpy.data.objects[n].photonlm.resolution = 0
    bpy.context.scene.photonlm.lightmap_layout = 'ATLAS'
    last = scenes.photonlm_bake(400_000, 4, seed=5, target_error=0.0)
    before = [photonlm.read_lightmap_exr(os.path.join(out, "Scene_atlas_%d_lightmap.exr" % k)) for k in range(pages)]
    checks.check(bpy.context.scene[atlas.LAYOUT_KEY].to_dict()["blocks"] == layout["blocks"]
                 and all(np.array_equal(a.rgb, b.rgb) for a, b in zip(before, page_data)),
                 "baking the atlas again (same seed) gives the same layout and pages")
    chosen = ("obj_03", "obj_20")
    res = bake_selected(chosen, 6)
    now = bpy.context.scene[atlas.LAYOUT_KEY].to_dict()
    after = [photonlm.read_lightmap_exr(os.path.join(out, "Scene_atlas_%d_lightmap.exr" % k)) for k in range(pages)]
    masks = [np.zeros((PAGE, PAGE), bool) for _ in range(pages)]
    for n in chosen:
        c = places[n].cell(pad)
        masks[places[n].page][c[1]:c[3], c[0]:c[2]] = True
    same_outside = all(np.array_equal(a.rgb[~m], b.rgb[~m]) and np.array_equal(a.error[~m], b.error[~m])
                       for a, b, m in zip(after, before, masks))
    new_inside = all(not np.array_equal(after[places[n].page].rgb[masks[places[n].page]],
                                        before[places[n].page].rgb[masks[places[n].page]]) for n in chosen)
    checks.check(res == {'FINISHED'} and now["blocks"] == layout["blocks"] and same_outside and new_inside,
                 "Bake Selected (%s): same layout, texels outside the selected cells unchanged, inside new" % (res,))

    grown = "obj_04"
    bpy.data.objects[grown].photonlm.density_scale = 2.0
    res = bake_selected((grown,), 7)
    now = bpy.context.scene[atlas.LAYOUT_KEY].to_dict()
    moved = atlas_pack.Placement(*now["blocks"][grown])
    others_kept = all(now["blocks"][n] == layout["blocks"][n] for n in names if n != grown)
    pairs, outside = atlas_pack.overlapping([atlas_pack.Placement(*b) for b in now["blocks"].values()], pad, PAGE)
    _, auv = surface_uvs(bpy.data.objects[grown])
    inside = bool((auv >= np.array([moved.x, moved.y]) / PAGE - 1e-6).all()
                  and (auv <= np.array([moved.x + moved.w, moved.y + moved.h]) / PAGE + 1e-6).all())
    checks.check(res == {'FINISHED'} and moved.w > 1.9 * places[grown].w and others_kept and not pairs
                 and not outside and inside,
                 "a grown block (%d -> %d texels) moves to free space (page %d), nothing else moves, no overlap"
                 % (places[grown].w, moved.w, moved.page))

    bpy.context.scene.photonlm.atlas_size = '1024'
    stamp = {f: os.path.getmtime(os.path.join(out, f)) for f in os.listdir(out) if f.endswith(".exr")}
    res = bake_selected(chosen, 8)
    checks.check("another page size" in str(res) and stamp == {f: os.path.getmtime(os.path.join(out, f))
                                                                  for f in os.listdir(out) if f.endswith(".exr")},
                 "Bake Selected after the page size changed is refused and changes no file: %s" % res)
    bpy.context.scene.photonlm.atlas_size = str(PAGE)
    bpy.data.objects["floor"].photonlm.density_scale = 1.0  # 960 texels wanted: capped to fit a page
    last = scenes.photonlm_bake(400_000, 4, seed=5, target_error=0.0)
    capped = [t for level, t in last["reports"] if "'floor' fills a whole atlas page" in t]
    checks.check(last["objects"]["floor"]["size"] == (PAGE - 2 * pad,) * 2 and len(capped) == 1,
                 "an object too large for a page at the density is capped to fit, with a warning: %s" % capped)
    bpy.data.objects["obj_10"].photonlm.resolution = 600
    try:
        res = bpy.ops.photonlm.bake()
    except RuntimeError as e:
        res = str(e)
    checks.check("'obj_10' (600 x 600)" in str(res) and "Page Size" in str(res),
                 "a Resolution too large for a page is refused naming the object: %s" % res)
    bpy.data.objects["obj_10"].photonlm.resolution = 0

    # -- Remove Preview --------------------------------------------------------------------------------
    bpy.ops.photonlm.remove_preview()
    checks.check(not any(wiring.is_wired(m) for m in bpy.data.materials),
                 "Remove Preview removes the atlas preview from every material")
    checks.finish()


main()
