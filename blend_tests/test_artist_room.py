"""An artist's room (scenes.artist_room): automatic lightmap UVs under Solidify, Boolean, Array,
Mirror, Bevel and Subdivision Surface modifiers, baked through the add-on.

Expected:
1. First bake: no engine warning about overlapping UV islands, zero-area or out-of-square
   triangles; every object's evaluated mesh carries a 'lightmap' UV map that is clean at its
   lightmap resolution (uvcheck: no overlapping or shared texels, no folds, islands at least 2
   texels apart) and Suzanne keeps the engine's subdivision (its map is made for the cage and
   stays valid after refinement); every lightmap is lit; the inside of the sunlit window wall is
   far darker than its outside (no texel shared between the two sides of a Solidify wall).
2. The artists' data is unchanged: same vertices, loops, positions and other UV maps (data,
   active and render flags) in every mesh, the same modifiers with the same settings in every
   stack; what the add-on adds is the 'lightmap' UV map of each mesh and, where modifiers change
   the topology, one Data Transfer modifier 'PhotonLM Lightmap UV' (at the end of the stack, or
   before a last Subdivision Surface) fed by a helper object that is in no scene.
3. Saved and opened again, the evaluated meshes carry the same maps; a second bake reuses every
   map (nothing is unwrapped again) and gives no UV warnings.
4. Native Subdivision off: Suzanne's map is made for Blender's subdivided mesh; no UV warnings.
5. Eight objects sharing a user-made 'lightmap' map whose islands overlap: the map is used as
   it is and the engine's eight identical warnings come back as one summary line.
About 20 s.
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

UV_WARNINGS = ("overlap", "zero lightmap UV area", "outside the [0, 1]")
SETTINGS = dict(direct_samples=16)


def mesh_state(obj):
    """What must not change in the user's data: mesh geometry, UV maps other than 'lightmap',
    active flags, and the user's modifiers with their settings."""
    me = obj.data
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    uvs = {}
    for layer in me.uv_layers:
        if layer.name == "lightmap":
            continue
        a = np.empty(len(me.loops) * 2, np.float32)
        layer.data.foreach_get("uv", a)
        uvs[layer.name] = a.tobytes()
    active = me.uv_layers.active.name if me.uv_layers.active else None
    render = [l.name for l in me.uv_layers if l.active_render]
    mods = []
    for m in obj.modifiers:
        if m.name.startswith("PhotonLM Lightmap UV"):
            continue
        props = []
        for p in m.bl_rna.properties:
            if p.identifier in ("rna_type", "is_override_data", "show_expanded") or p.type == 'COLLECTION':
                continue
            v = getattr(m, p.identifier)
            if p.type == 'POINTER':
                v = getattr(v, "name", None)
            elif hasattr(v, "__len__") and not isinstance(v, str):
                v = tuple(v)
            props.append((p.identifier, v))
        mods.append((m.name, m.type, tuple(props)))
    return dict(verts=len(me.vertices), loops=len(me.loops), co=co.tobytes(), uvs=uvs, active=active,
                render=render, mods=mods, uv_names=[l.name for l in me.uv_layers])


def side_means(walls, rgb):
    """Area-weighted mean lightmap value over the inside (x = 3) and the outside (x = 3.2) of the
    window wall, sampled at points inside each of their triangles."""
    pos, uv = scenes.evaluated_lightmap_triangles(walls)
    n = np.cross(pos[:, 1] - pos[:, 0], pos[:, 2] - pos[:, 0])
    area = 0.5 * np.linalg.norm(n, axis=1)
    nx = np.abs(n[:, 0]) / np.maximum(2 * area, 1e-30)
    cx = pos[:, :, 0].mean(axis=1)
    h, w = rgb.shape[:2]
    k = 8
    bary = np.array([(i + 1 / 3, j + 1 / 3) for i in range(k) for j in range(k - i)]) / k
    bary = np.column_stack([1 - bary.sum(axis=1), bary])
    out = []
    for side in (np.abs(cx - 3.0) < 0.01, np.abs(cx - 3.2) < 0.01):
        sel = (nx > 0.99) & side & (area > 1e-6)
        pts = np.einsum("sk,tkd->tsd", bary, uv[sel])
        ix = np.clip((pts[..., 0] * w).astype(int), 0, w - 1)
        iy = np.clip((pts[..., 1] * h).astype(int), 0, h - 1)
        vals = rgb[iy, ix].mean(axis=-1).mean(axis=1)
        out.append((float((vals * area[sel]).sum() / area[sel].sum()), int(sel.sum())))
    return out


def check_maps(checks, objs, last, what):
    from photonlm_blender.uv import uvcheck
    for name in scenes.ARTIST_ROOM_OBJECTS:
        obj = objs[name]
        pos, uv = scenes.evaluated_lightmap_triangles(obj)
        res = last["objects"][name]["size"][0]
        if not checks.check(uv is not None, "%s: %s: the evaluated mesh has a 'lightmap' UV map" % (what, name)):
            continue
        st = uvcheck.analyse(uv, res, pos)
        checks.check(uvcheck.clean(st), "%s: %s: evaluated map at %d x %d: %s" % (what, name, res, res,
                                                                               uvcheck.describe(st)))


def uv_warnings(last):
    return [w for w in last["warnings"] if any(k in w for k in UV_WARNINGS)]


def evaluated_uvs(objs):
    return {n: scenes.evaluated_lightmap_triangles(objs[n])[1] for n in scenes.ARTIST_ROOM_OBJECTS}


def main():
    checks = scenes.Checks("artist_room")
    scenes.setup_paths()
    from photonlm_blender.uv import uvmaps
    scenes.clear_scene()
    out = scenes.out_dir("artist_room")
    objs = scenes.artist_room(out)
    scene = bpy.context.scene
    scene.photonlm.output_dir = out
    before = {n: mesh_state(o) for n, o in objs.items()}

    # -- 1. first bake -------------------------------------------------------------------------------------
    last = scenes.photonlm_bake(2_000_000, 8, seed=1, target_error=0.05, **SETTINGS)
    reports = [t for _, t in last["reports"]]
    print("first bake: %.1f s (UVs and export %.1f s)" % (last["wall_seconds"], last["stats"]["seconds_export"]))
    checks.check(not uv_warnings(last), "first bake: no UV warnings from the engine %s" % uv_warnings(last)[:3])
    checks.check(sorted(last["objects"]) == sorted(scenes.ARTIST_ROOM_OBJECTS),
                 "every object baked, the cutters (hidden from render) not: %s" % sorted(last["objects"]))
    check_maps(checks, objs, last, "first bake")
    checks.check(any("'Suzanne': subdivision level 2 refined by the engine" in t for t in reports) and
                 any("'Suzanne': lightmap UV map made for its subdivision cage" in t for t in reports),
                 "Suzanne keeps the engine's subdivision, its map made for the cage")
    for name in scenes.ARTIST_ROOM_OBJECTS:
        info = last["objects"][name]
        cov = np.asarray(info["coverage"])
        mean = float(np.asarray(info["rgb"])[cov > 0.5].mean())
        checks.check(mean > 0.0, "%s: lightmap lit (mean %.4g over %d texels)" % (name, mean, int((cov > 0.5).sum())))
    (inside, n_in), (outside, n_out) = side_means(objs["Walls"], np.asarray(last["objects"]["Walls"]["rgb"]))
    checks.check(n_in > 0 and n_out > 0 and inside < 0.25 * outside,
                 "window wall: inside %.4f (%d triangles) is far darker than outside %.4f (%d triangles): ratio %.3f "
                 "(limit 0.25)" % (inside, n_in, outside, n_out, inside / max(outside, 1e-30)))

    # -- 2. the user's data --------------------------------------------------------------------------------
    for name, obj in objs.items():
        now, was = mesh_state(obj), before[name]
        same_mesh = all(now[k] == was[k] for k in ("verts", "loops", "co", "uvs", "active", "render"))
        checks.check(same_mesh, "%s: mesh unchanged (%d vertices, %d loops, UV maps %s, active %s, render %s)"
                     % (name, now["verts"], now["loops"], sorted(now["uvs"]), now["active"], now["render"]))
        checks.check(now["mods"] == was["mods"], "%s: its modifiers and their settings unchanged (%s)"
                     % (name, [m[0] for m in now["mods"]]))
        added = [n for n in now["uv_names"] if n not in was["uv_names"]]
        ours = [m for m in obj.modifiers if m.name.startswith("PhotonLM Lightmap UV")]
        baked = name in scenes.ARTIST_ROOM_OBJECTS
        checks.check(added == (["lightmap"] if baked else []) and len(ours) <= (1 if baked else 0),
                     "%s: the add-on added UV maps %s and modifiers %s" % (name, added, [m.name for m in ours]))
        if ours:
            idx = list(obj.modifiers).index(ours[0])
            users = [m for m in obj.modifiers if m != ours[0]]
            place_ok = idx == len(users) or (idx == len(users) - 1 and users[-1].type == 'SUBSURF')
            helper = ours[0].object
            checks.check(place_ok and helper is not None and not helper.users_collection and helper.use_fake_user,
                         "%s: 'PhotonLM Lightmap UV' at %d of %d, fed by '%s' (in no scene, fake user)"
                         % (name, idx, len(obj.modifiers), getattr(helper, "name", None)))
    checks.check(not any(objs[n].modifiers.get("PhotonLM Lightmap UV") for n in ("Floor", "Ball", "Suzanne")),
                 "objects whose evaluated mesh has the mesh's own topology keep their map in the mesh (no modifier)")

    # -- 3. save, open again, bake again --------------------------------------------------------------------
    maps = evaluated_uvs(objs)
    path = os.path.join(out, "artist_room.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    scenes.setup_paths()
    objs = {n: bpy.data.objects[n] for n in scenes.ARTIST_ROOM_OBJECTS}
    again = evaluated_uvs(objs)
    same = [n for n in maps if again[n] is not None and np.array_equal(again[n], maps[n])]
    checks.check(len(same) == len(maps), "reopened file: the evaluated maps are the same (%s)" % sorted(same))
    last2 = scenes.photonlm_bake(2_000_000, 8, seed=2, target_error=0.05, **SETTINGS)
    reports2 = [t for _, t in last2["reports"]]
    made = [t for t in reports2 if "lightmap UV map made" in t]
    checks.check(not made and not uv_warnings(last2), "second bake reuses every map (%d made again: %s), no UV "
                 "warnings %s" % (len(made), made[:2], uv_warnings(last2)[:2]))
    again = evaluated_uvs(objs)
    checks.check(all(np.array_equal(again[n], maps[n]) for n in maps), "second bake: the maps are unchanged")

    # -- 4. Native Subdivision off -----------------------------------------------------------------------------
    last3 = scenes.photonlm_bake(500_000, 4, seed=3, target_error=0.0, native_subdivision=False, **SETTINGS)
    reports3 = [t for _, t in last3["reports"]]
    checks.check(not uv_warnings(last3) and any("'Suzanne': lightmap UV map made for its mesh after modifiers" in t
                                                for t in reports3),
                 "Native Subdivision off: Suzanne's map is made for Blender's subdivided mesh, no UV warnings %s"
                 % uv_warnings(last3)[:2])
    check_maps(checks, objs, last3, "native subdivision off")
    scene = bpy.context.scene
    scene.photonlm.native_subdivision = True

    # -- 5. a user's map with overlaps on eight objects ------------------------------------------------------
    for o in list(bpy.data.objects):
        o.photonlm.enabled = False
    mat = scenes.diffuse_material("mat_tiles", (0.6, 0.6, 0.6))
    quads = [((-0.5, -0.5, 0.01), (0.5, -0.5, 0.01), (0.5, 0.5, 0.01), (-0.5, 0.5, 0.01), (0.0, 0.0, 1.0, 1.0)),
             ((-0.5, -0.5, 0.3), (0.5, -0.5, 0.3), (0.5, 0.5, 0.3), (-0.5, 0.5, 0.3), (0.0, 0.0, 1.0, 1.0))]
    first = scenes.quads_object("Tiles", quads, mat, 16)
    for k in range(1, 8):
        copy = first.copy()  # a linked duplicate: the same mesh and map
        copy.name = "Tiles.%03d" % k
        copy.location = (-2.0 + 0.6 * (k % 4), -1.5 + 1.2 * (k // 4), 0.0)
        scene.collection.objects.link(copy)
    first.location = (-2.6, -1.5, 0.0)
    last4 = scenes.photonlm_bake(200_000, 2, seed=4, target_error=0.0, **SETTINGS)
    overlap_raw = [w for w in last4["warnings"] if "overlap" in w]
    overlap_lines = [t for _, t in last4["reports"] if t.startswith("engine:") and "overlap" in t]
    checks.check(len(overlap_raw) == 8 and len(overlap_lines) == 1 and "8 meshes" in overlap_lines[0],
                 "eight objects with the same overlapping map: %d engine warnings, reported as %s"
                 % (len(overlap_raw), overlap_lines))
    checks.check(np.array_equal(scenes.evaluated_lightmap_triangles(first)[1].reshape(-1, 3, 2)[0],
                                np.array([[0, 0], [1, 0], [1, 1]], np.float32)),
                 "the user's map is used as it is")
    lines = uvmaps.summarise_warnings(["mesh 'A': 3 triangles have zero lightmap UV area (first: triangle 4); x",
                                       "mesh 'B': 5 triangles have zero lightmap UV area (first: triangle 0); x",
                                       "something else"])
    checks.check(len(lines) == 3, "up to three meshes with one problem keep a line each: %s" % lines)
    checks.finish()


main()
