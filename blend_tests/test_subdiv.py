"""Subdivision surfaces refined by the engine (OpenSubdiv) against Blender's own Subdivision Surface
modifier (defaults: limit surface, boundary smooth ALL, UV smooth PRESERVE_BOUNDARIES, creases).

Expected:
1. Geometry: for a cube cage at levels 1-3, a creased cube (crease 1.0 loop + a 0.5 edge), a 4 x 4
   grid (open boundary) and Suzanne (triangles and quads), the engine's refined vertices match
   Blender's evaluated mesh one-to-one within 1e-5 of the object's size, and every (vertex, UV)
   corner of one has a twin in the other within 1e-5 in UV. A cage read through the add-on's
   toggle path (an Array modifier before the subdivision) matches too, and the modifier's
   viewport switch is restored.
2. Bake: a subdivided cube (level 3) on a floor under a sun and the sky, baked through the add-on
   as a cage and as Blender's refined mesh: the lightmaps agree within the noise (RMS difference
   cage-vs-mesh at most 1.5 x the RMS difference of two mesh bakes with other seeds; with the
   same seed at most half that; means of two bakes each within 1.5 %), the report says which
   path each took, and a SIMPLE subdivision falls back with its reason. About 10 s.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils import kdtree  # noqa: E402

TOL = 1e-5


def add_subsurf(obj, level):
    mod = obj.modifiers.new("Subdivision", 'SUBSURF')
    mod.levels = level
    mod.render_levels = level
    return mod


def cube(name, level, location=(0, 0, 0)):
    bpy.ops.mesh.primitive_cube_add(size=2, location=location)
    obj = bpy.context.active_object
    obj.name = name
    obj.data.uv_layers[0].name = "lightmap"
    add_subsurf(obj, level)
    return obj


def blender_refined(obj):
    """World positions (V, 3) and per-loop (vertex, uv) of Blender's evaluated mesh."""
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg)
    me = ev.to_mesh()
    try:
        n = len(me.vertices)
        co = np.empty(n * 3, np.float32)
        me.vertices.foreach_get("co", co)
        m = np.array(obj.matrix_world, np.float64)
        pos = co.reshape(n, 3) @ m[:3, :3].T + m[:3, 3]
        lv = np.empty(len(me.loops), np.int32)
        me.loops.foreach_get("vertex_index", lv)
        uv = np.empty(len(me.loops) * 2, np.float32)
        me.uv_layers["lightmap"].data.foreach_get("uv", uv)
        return pos, lv, uv.reshape(-1, 2)
    finally:
        ev.to_mesh_clear()


def compare(checks, what, obj, cage):
    import photonlm
    pos_e, tris_e, uv_e = photonlm.subdiv_refine(cage.positions, cage.face_sizes, cage.face_indices, cage.level,
                                                 lightmap_uv=cage.uv, crease_edges=cage.crease_edges,
                                                 crease_weights=cage.crease_weights)
    pos_b, loop_v, loop_uv = blender_refined(obj)
    size = float(np.max(np.ptp(pos_b, axis=0)))
    tree = kdtree.KDTree(len(pos_b))
    for i, p in enumerate(pos_b):
        tree.insert(p, i)
    tree.balance()
    match = np.empty(len(pos_e), np.int64)
    dist = np.empty(len(pos_e))
    for i, p in enumerate(pos_e):
        _, j, d = tree.find(p)
        match[i], dist[i] = j, d
    one_to_one = len(pos_e) == len(pos_b) and len(np.unique(match)) == len(pos_b)
    checks.check(one_to_one and dist.max() <= TOL * size,
                 "%s: %d engine vs %d Blender vertices, one-to-one %s, max distance %.2e (limit %.1e = 1e-5 x size %.3g)"
                 % (what, len(pos_e), len(pos_b), one_to_one, dist.max(), TOL * size, size))
    # (vertex, uv) corners as sets, vertices mapped through the match.
    def corner_set(verts, uvs):
        out = {}
        for v, (u, w) in zip(verts, uvs):
            out.setdefault(int(v), []).append((float(u), float(w)))
        return out
    eng = corner_set(match[tris_e.ravel()], uv_e.reshape(-1, 2))
    ble = corner_set(loop_v, loop_uv)

    def worst(a, b):
        w = 0.0
        for v, uvs in a.items():
            others = np.array(b.get(v, [(1e9, 1e9)]))
            for uv in uvs:
                w = max(w, float(np.min(np.max(np.abs(others - np.array(uv)), axis=1))))
        return w
    w = max(worst(eng, ble), worst(ble, eng))
    checks.check(w <= TOL, "%s: worst UV corner mismatch %.2e (limit %.0e)" % (what, w, TOL))


def geometry(checks):
    from photonlm_blender.export import subdiv as subdiv_export
    for level in (1, 2, 3):
        scenes.clear_scene()
        obj = cube("Cube", level)
        compare(checks, "cube level %d" % level, obj, subdiv_export.read_cage(obj.data, obj.matrix_world, level, True))

    scenes.clear_scene()
    obj = cube("Creased", 2)
    me = obj.data
    top = [e for e in me.edges if all(me.vertices[v].co.z > 0 for v in e.vertices)]
    for e in top:
        scenes.set_edge_crease(me, e.index, 1.0)
    vertical = [e for e in me.edges if me.vertices[e.vertices[0]].co.z != me.vertices[e.vertices[1]].co.z]
    scenes.set_edge_crease(me, vertical[0].index, 0.5)
    cage = subdiv_export.read_cage(me, obj.matrix_world, 2, True)
    checks.check(cage.crease_edges is not None and len(cage.crease_edges) == 5, "creased cube: 5 crease edges read")
    compare(checks, "creased cube level 2", obj, cage)

    scenes.clear_scene()
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=5, y_subdivisions=5, size=2, calc_uvs=True)
    obj = bpy.context.active_object
    obj.data.uv_layers[0].name = "lightmap"
    add_subsurf(obj, 2)
    compare(checks, "grid level 2", obj, subdiv_export.read_cage(obj.data, obj.matrix_world, 2, True))

    scenes.clear_scene()
    bpy.ops.mesh.primitive_monkey_add(size=2, location=(0.3, -0.2, 0.1), rotation=(0.3, 0.2, 0.1))
    obj = bpy.context.active_object
    obj.data.uv_layers[0].name = "lightmap"
    add_subsurf(obj, 2)
    compare(checks, "Suzanne level 2", obj, subdiv_export.read_cage(obj.data, obj.matrix_world, 2, True))

    # The add-on's toggle path: an Array modifier before the subdivision.
    scenes.clear_scene()
    obj = cube("Arrayed", 2)
    arr = obj.modifiers.new("Array", 'ARRAY')
    arr.count = 2
    arr.relative_offset_displace = (1.5, 0, 0)
    bpy.ops.object.modifier_move_to_index(modifier="Array", index=0)
    from photonlm_blender.export.scene import Reports
    reports = Reports()
    cages = subdiv_export.read_cages(bpy.context, subdiv_export.candidates([obj], reports), reports)
    sub = obj.modifiers["Subdivision"]
    checks.check(sub.show_viewport, "the subdivision modifier's viewport switch is restored")
    checks.check("Arrayed" in cages and len(cages["Arrayed"].face_sizes) == 12,
                 "arrayed cube read as a 12-face cage (modifiers before the subdivision apply)")
    if "Arrayed" in cages:
        compare(checks, "arrayed cube level 2", obj, cages["Arrayed"])


def bake_scene():
    scenes.clear_scene()
    obj = cube("Blob", 3, location=(0, 0, 1.2))
    obj.photonlm.enabled = True
    obj.photonlm.resolution = 32
    bpy.ops.mesh.primitive_plane_add(size=8)
    floor = bpy.context.active_object
    floor.name = "Floor"
    grey = scenes.diffuse_material("grey", (0.6, 0.6, 0.6))
    obj.data.materials.append(grey)
    floor.data.materials.append(grey)
    scenes.add_light("Sun", 'SUN', (0, 0, 5), rotation=(0.5, 0.3, 0), energy=3.0)
    scenes.set_world_color((0.2, 0.25, 0.3), 1.0)
    simple = cube("Simple", 1, location=(3, 0, 1))
    simple.modifiers["Subdivision"].subdivision_type = 'SIMPLE'
    bpy.context.scene.photonlm.output_dir = scenes.out_dir("subdiv")
    return obj


def bake(checks):
    bake_scene()
    runs = {}
    for key, native, seed in (("mesh1", False, 1), ("mesh2", False, 2), ("cage", True, 3), ("cage1", True, 1)):
        last = scenes.photonlm_bake(1_500_000, 16, seed=seed, target_error=0.0, native_subdivision=native)
        reports = [t for _, t in last["reports"]]
        runs[key] = last["objects"]["Blob"]
        print("%s: export %.3f s, bake %.2f s" % (key, last["stats"]["seconds_export"],
                                                  last["stats"]["seconds_total"]), flush=True)
        cage_note = any("'Blob': subdivision level 3 refined by the engine" in r for r in reports)
        checks.check(cage_note == native, "%s: the report says the cage path was %s" % (key, "taken" if native else "not taken"))
        if native:
            checks.check(any("'Simple': exported as Blender's subdivided mesh: subdivision type SIMPLE" in r
                             for r in reports), "SIMPLE subdivision falls back with its reason")
    mask = (runs["mesh1"]["coverage"] > 0.999) & (runs["cage"]["coverage"] > 0.999) & \
        (runs["mesh2"]["coverage"] > 0.999)
    cov_diff = int(((runs["mesh1"]["coverage"] > 0.5) != (runs["cage"]["coverage"] > 0.5)).sum())
    checks.check(cov_diff <= 4, "coverage masks agree (%d texels differ, limit 4)" % cov_diff)
    a, b, c, d = (runs[k]["rgb"].mean(axis=2)[mask] for k in ("mesh1", "mesh2", "cage", "cage1"))
    noise = float(np.sqrt(np.mean((a - b) ** 2)))
    diff = float(np.sqrt(np.mean((a - c) ** 2)))
    checks.check(diff <= 1.5 * noise, "RMS difference cage vs mesh %.4g, mesh vs mesh (other seed) %.4g "
                 "(limit 1.5x), %d texels, mean %.4g" % (diff, noise, int(mask.sum()), float(a.mean())))
    same = float(np.sqrt(np.mean((a - d) ** 2)))
    # Equal seeds share most random numbers (bit-identical while sampling did not depend on the
    # triangle order; 2.8e-7 RMS then), so the difference stays well below the seed noise.
    checks.check(same <= 0.5 * noise, "same seed: RMS difference cage vs mesh %.3g (limit half the seed noise %.4g)"
                 % (same, noise))
    # Means: the bake's mean itself moves ~0.8 % between seeds (measured: mesh seed 2 / seed 1), so
    # the two cage bakes' mean is compared with the two mesh bakes' mean within 1.5 %.
    m_cage, m_mesh = 0.5 * (c.mean() + d.mean()), 0.5 * (a.mean() + b.mean())
    checks.check(abs(m_cage / m_mesh - 1) < 0.015, "means cage %.4f mesh %.4f (ratio %.4f, limit 1.5%%); mesh seeds "
                 "1 vs 2 ratio %.4f" % (m_cage, m_mesh, m_cage / m_mesh, b.mean() / a.mean()))


def main():
    checks = scenes.Checks("subdiv")
    scenes.setup_paths()
    geometry(checks)
    bake(checks)
    checks.finish()


main()
