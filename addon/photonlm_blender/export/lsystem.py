"""L-system objects: rules in `object.photonlm.lsystem`, a capped preview mesh made by the engine,
baked as a cyclic scene graph (never flattened) lit through orientation lightmaps.

The preview mesh is only for the viewport (and for showing the bake): the engine traces the
rules themselves. After a bake the preview mesh gets a point colour attribute `photonlm_light`
(irradiance / pi at each vertex, from the object's orientation lightmaps) that a material can
multiply with its colour (writeback/lsystem.py).
"""
import numpy as np

from .. import bridge

LIGHT_ATTRIBUTE = "photonlm_light"

# Presets: (rules text, settings). The language is documented in the engine's lsystem.h.
PRESETS = {
    'SIERPINSKI': (
        "# Sierpinski triangle (F-G-G, F -> F-G+F+G-F, G -> GG) drawn with cylinders\n"
        "angle: 120\n"
        "axiom: A(5) - B(5) - B(5)\n"
        "A(n) : n > 0 -> A(n-1) - B(n-1) + A(n-1) + B(n-1) - A(n-1)\n"
        "A(n) : n <= 0 -> F\n"
        "B(n) : n > 0 -> B(n-1) B(n-1)\n"
        "B(n) : n <= 0 -> F\n",
        dict(depth=6, step=0.1, width=0.03)),
    'SYMPODIAL_TREE': (
        "# A sympodial tree (after ABOP figure 2.7): two unequal branches at every node\n"
        "const r1 = 0.9\n"
        "const r2 = 0.7\n"
        "const a1 = 10\n"
        "const a2 = 60\n"
        "const wr = 0.707\n"
        "axiom: A(1, 0.1)\n"
        "A(l, w) -> !(w) F(l) [ &(a1) B(l*r1, w*wr) ] /(180) [ &(a2) B(l*r2, w*wr) ]\n"
        "B(l, w) -> !(w) F(l) [ +(a1) B(l*r1, w*wr) ] [ -(a2) B(l*r2, w*wr) ]\n",
        dict(depth=9, step=1.0, width=0.1)),
    'BUSH': (
        "# A bush (after ABOP figure 1.25) with round leaves at the branch tips\n"
        "angle: 22.5\n"
        "axiom: A\n"
        "A -> [ & F @O(0.06) A ] ///// [ & F @O(0.06) A ] /////// [ & F @O(0.06) A ]\n"
        "F -> S ///// F\n"
        "S -> F\n",
        dict(depth=6, step=0.2, width=0.03)),
}


def _settings(ls):
    return dict(depth=int(ls.depth), seed=int(ls.seed), step=float(ls.step) if ls.step > 0 else -1.0,
                width=float(ls.width) if ls.width > 0 else -1.0)


# ---- preview mesh ------------------------------------------------------------------------------

def _unit_shapes():
    """Low-poly canonical shapes (engine conventions): name -> (vertices (V, 3), triangles (T, 3))."""
    n = 8
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a)], axis=1)
    cyl_v = np.concatenate([np.c_[ring, -np.ones(n)], np.c_[ring, np.ones(n)], [[0, 0, -1], [0, 0, 1]]])
    cyl_t = []
    for i in range(n):
        j = (i + 1) % n
        cyl_t += [(i, j, n + j), (i, n + j, n + i), (2 * n, j, i), (2 * n + 1, n + i, n + j)]
    cone_v = np.concatenate([np.c_[ring, -np.ones(n)], [[0, 0, 1], [0, 0, -1]]])
    cone_t = []
    for i in range(n):
        j = (i + 1) % n
        cone_t += [(i, j, n), (n + 1, j, i)]
    box_v = np.array([[x, y, z] for z in (-1, 1) for y in (-1, 1) for x in (-1, 1)], float)
    box_t = [(0, 2, 3), (0, 3, 1), (4, 5, 7), (4, 7, 6), (0, 1, 5), (0, 5, 4),
             (2, 6, 7), (2, 7, 3), (0, 4, 6), (0, 6, 2), (1, 3, 7), (1, 7, 5)]
    # Octahedron refined once, pushed to the unit sphere.
    oct_v = [np.array(v, float) for v in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))]
    oct_t = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    sph_v, sph_t = list(oct_v), []
    mid = {}

    def m(i, j):
        key = (min(i, j), max(i, j))
        if key not in mid:
            p = sph_v[i] + sph_v[j]
            sph_v.append(p / np.linalg.norm(p))
            mid[key] = len(sph_v) - 1
        return mid[key]
    for (i, j, k) in oct_t:
        a_, b_, c_ = m(i, j), m(j, k), m(k, i)
        sph_t += [(i, a_, c_), (a_, j, b_), (c_, b_, k), (a_, b_, c_)]
    return {"CYLINDER": (cyl_v, np.array(cyl_t)), "CONE": (cone_v, np.array(cone_t)),
            "BOX": (box_v, np.array(box_t)), "SPHERE": (np.array(sph_v), np.array(sph_t))}


_SHAPE_NAMES = {0: "SPHERE", 1: "BOX", 2: "CYLINDER", 3: "CONE"}


def preview_arrays(rules, settings, cap):
    """World-free (object-local) preview geometry: vertices (V, 3), triangles (T, 3), material per
    triangle, and whether the cap cut it."""
    photonlm = bridge.get()
    shapes, matrices, mats, truncated = photonlm.lsystem_flatten(rules, max_primitives=cap, **settings)
    units = _unit_shapes()
    verts, tris, tri_mats = [], [], []
    base = 0
    for code, m, mat in zip(shapes, matrices, mats):
        v, t = units[_SHAPE_NAMES.get(int(code), "BOX")]
        verts.append(v @ m[:, :3].T + m[:, 3])
        tris.append(t + base)
        tri_mats.append(np.full(len(t), mat, np.int32))
        base += len(v)
    if not verts:
        return np.zeros((0, 3)), np.zeros((0, 3), int), np.zeros(0, np.int32), truncated
    return np.concatenate(verts), np.concatenate(tris), np.concatenate(tri_mats), truncated


def update_preview(obj, reports=None):
    """Rebuild obj's mesh from its rules (capped). Raises the engine's error on bad rules."""
    ls = obj.photonlm.lsystem
    v, t, mats, truncated = preview_arrays(ls.rules, _settings(ls), int(ls.preview_cap))
    mesh = obj.data
    mesh.clear_geometry()
    mesh.vertices.add(len(v))
    mesh.vertices.foreach_set("co", v.astype(np.float32).ravel())
    mesh.loops.add(3 * len(t))
    mesh.loops.foreach_set("vertex_index", t.astype(np.int32).ravel())
    mesh.polygons.add(len(t))
    mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * len(t), 3, dtype=np.int32))
    mesh.polygons.foreach_set("loop_total", np.full(len(t), 3, np.int32))
    if len(t):
        slots = max(1, len(obj.material_slots))
        mesh.polygons.foreach_set("material_index", np.clip(mats, 0, slots - 1).astype(np.int32))
    mesh.update()
    mesh.validate()
    if truncated and reports is not None:
        reports.append("L-system '%s': preview capped at %d primitives (the bake uses all of them)"
                       % (obj.name, ls.preview_cap))
    return len(t)


# ---- bake: export and results --------------------------------------------------------------------

def is_lsystem(obj):
    return obj.type == 'MESH' and obj.photonlm.lsystem.enabled and obj.photonlm.lsystem.rules.strip() != ""


def export_lsystem(plm, obj, matrix, material_ids):
    """Add obj's rules to the bridge scene; returns its id."""
    ls = obj.photonlm.lsystem
    m = np.array(matrix, np.float64)
    return plm.add_lsystem(obj.name, ls.rules, matrix=m, materials=material_ids, ol_level=int(ls.ol_level),
                           **_settings(ls))
