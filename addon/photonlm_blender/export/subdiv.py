"""Subdivision surfaces exported as their cage.

An object whose last modifier is a Catmull-Clark Subdivision Surface (render_levels > 0)
with Blender's default options is exported as the mesh *before* that modifier (its cage:
earlier modifiers still apply), with its edge creases, the `lightmap` UV per loop and the
modifier's render level; the engine refines it with OpenSubdiv
(photonlm.Scene.add_subdiv_mesh), so Python moves the cage instead of the refined mesh.
Anything else (SIMPLE type, adaptive subdivision, non-default options, vertex creases,
image-textured materials, instances) falls back to Blender's refined mesh, with the reason in the bake report.

An automatic lightmap UV is made for the cage (uv/uvmaps.py: a Data Transfer modifier just before
the last Subdivision Surface, or the mesh's own map) and checked after the engine's refinement;
Blender's subdivided UV (uv_smooth PRESERVE_BOUNDARIES) is what the engine computes.
"""
import numpy as np

from .. import compat
from . import meshes


class Cage:
    """A cage read into numpy: everything add_subdiv_mesh needs, in world space."""

    def __init__(self, positions, face_sizes, face_indices, uv, material_index, crease_edges, crease_weights,
                 level, area, smooth=False):
        self.positions = positions
        self.face_sizes = face_sizes
        self.face_indices = face_indices
        self.uv = uv
        self.material_index = material_index
        self.crease_edges = crease_edges
        self.crease_weights = crease_weights
        self.level = level
        self.area = area  # of the cage (a slight overestimate of the limit surface's)
        self.smooth = smooth  # every face shaded smooth (else every face flat)

    def triangle_count(self):
        return 2 * int(self.face_sizes.sum()) * 4 ** (self.level - 1)

    def nbytes(self):
        return sum(a.nbytes for a in (self.positions, self.face_sizes, self.face_indices, self.uv,
                                      self.material_index, self.crease_edges, self.crease_weights)
                   if a is not None)


def last_subsurf(obj):
    mods = getattr(obj, "modifiers", None)
    if obj.type != 'MESH' or not mods:
        return None
    last = mods[-1]
    return last if last.type == 'SUBSURF' else None


def unsupported_reason(obj, mod):
    """None if the modifier can be refined by the engine, else why not (for the bake report)."""
    if not mod.show_viewport:
        return "its Subdivision Surface modifier is disabled in the viewport"
    if mod.subdivision_type != 'CATMULL_CLARK':
        return "subdivision type %s (only Catmull-Clark is refined natively)" % mod.subdivision_type
    cyc = getattr(obj, "cycles", None)
    if cyc is not None and getattr(cyc, "use_adaptive_subdivision", False):
        return "adaptive subdivision is on"
    if not mod.use_limit_surface:
        return "Use Limit Surface is off"
    if mod.boundary_smooth != 'ALL':
        return "boundary smooth %s (only ALL)" % mod.boundary_smooth
    if mod.uv_smooth != 'PRESERVE_BOUNDARIES':
        return "UV smooth %s (only PRESERVE_BOUNDARIES)" % mod.uv_smooth
    if mod.render_levels > 10:
        return "render level %d (at most 10)" % mod.render_levels
    return None


def candidates(objects, reports):
    """{name: (object, modifier)} of the objects to export as cages; reasons for the others reported."""
    out = {}
    for obj in objects:
        mod = last_subsurf(obj)
        if mod is None or mod.render_levels < 1:
            continue
        reason = unsupported_reason(obj, mod)
        if reason is not None:
            reports.info("object '%s': exported as Blender's subdivided mesh: %s" % (obj.name, reason))
            continue
        out[obj.name] = (obj, mod)
    return out


def read_cage(mesh, matrix_world, level, use_creases):
    """Cage arrays from a mesh (original or evaluated); None when it has no faces."""
    nv, nf, nl = len(mesh.vertices), len(mesh.polygons), len(mesh.loops)
    if nf == 0:
        return None
    vc = compat.vertex_creases(mesh) if use_creases else None
    if vc is not None and np.any(vc > 0):
        raise NotImplementedError("vertex creases are not supported")
    smooth = np.zeros(nf, dtype=bool)
    mesh.polygons.foreach_get("use_smooth", smooth)
    if smooth.any() and not smooth.all():
        raise NotImplementedError("some of its faces are shaded smooth and some flat")
    if smooth.any() and getattr(mesh, "has_custom_normals", False):
        raise NotImplementedError("it has custom normals")
    m = np.array(matrix_world, dtype=np.float64)
    pos = meshes.world_positions(mesh, m).astype(np.float32)
    sizes = np.empty(nf, np.uint32)
    mesh.polygons.foreach_get("loop_total", sizes)
    starts = np.empty(nf, np.uint32)
    mesh.polygons.foreach_get("loop_start", starts)
    loop_vert = np.empty(nl, np.uint32)
    mesh.loops.foreach_get("vertex_index", loop_vert)
    # Polygons store their loops contiguously; if not in order, gather them face by face.
    if nf and (starts[0] != 0 or np.any(starts[1:] != np.cumsum(sizes)[:-1])):
        first = np.cumsum(sizes, dtype=np.int64) - sizes  # where each face's loops go in the output
        order = np.repeat(starts.astype(np.int64) - first, sizes) + np.arange(int(sizes.sum()), dtype=np.int64)
    else:
        order = None
    face_indices = loop_vert if order is None else loop_vert[order]
    mat = np.empty(nf, np.int32)
    mesh.polygons.foreach_get("material_index", mat)
    uv = meshes.lightmap_uv(mesh)
    if uv is not None:
        if order is not None:
            uv = uv[order]
    edges = weights = None
    crease = compat.edge_creases(mesh) if use_creases else None
    if crease is not None:
        sel = np.flatnonzero(crease > 0)
        if sel.size:
            ev = np.empty(len(mesh.edges) * 2, np.uint32)
            mesh.edges.foreach_get("vertices", ev)
            edges = np.ascontiguousarray(ev.reshape(-1, 2)[sel])
            weights = np.ascontiguousarray(np.clip(crease[sel], 0.0, 1.0))
    area = 0.0
    try:
        pa = np.empty(nf, np.float32)
        mesh.polygons.foreach_get("area", pa)
        scale = abs(np.linalg.det(m[:3, :3])) ** (2.0 / 3.0)  # exact for uniform scale
        area = float(pa.sum()) * scale
    except (AttributeError, RuntimeError):
        pass
    return Cage(pos, sizes, face_indices, uv, mat, edges, weights, level, area, bool(smooth.all()))


def read_cages(context, cands, reports):
    """{name: Cage} for the candidates. An object whose subdivision is its only modifier (and
    has no shape keys) is read from its own mesh; the others are evaluated with the
    modifier hidden, which is restored in every case."""
    cages = {}
    toggled = []
    try:
        direct = []
        for name, (obj, mod) in cands.items():
            if len(obj.modifiers) == 1 and obj.data.shape_keys is None:
                direct.append(name)
            else:
                mod.show_viewport = False
                toggled.append(mod)
        depsgraph = context.evaluated_depsgraph_get()
        for name, (obj, mod) in cands.items():
            try:
                if name in direct:
                    cage = read_cage(obj.data, obj.matrix_world, mod.render_levels, mod.use_creases)
                else:
                    obj_eval = obj.evaluated_get(depsgraph)
                    mesh = obj_eval.to_mesh()
                    try:
                        cage = None if mesh is None else read_cage(mesh, obj.matrix_world, mod.render_levels,
                                                                     mod.use_creases)
                    finally:
                        obj_eval.to_mesh_clear()
            except NotImplementedError as e:
                reports.info("object '%s': exported as Blender's subdivided mesh: %s" % (name, e))
                continue
            except Exception as e:  # noqa: BLE001 -- never let one object stop the export
                reports.warning("object '%s': exported as Blender's subdivided mesh: reading its cage failed (%s)"
                                % (name, e))
                continue
            if cage is not None:
                cages[name] = cage
    finally:
        for mod in toggled:
            mod.show_viewport = True
        if toggled:
            context.evaluated_depsgraph_get()  # re-evaluate with the modifiers back
    return cages


def add_cage(plm, name, cage, with_lightmap, slot_ids, resolution):
    """Add the cage to the photonlm scene; returns the mesh id (raises the engine's error)."""
    mat_ids = slot_ids[np.clip(cage.material_index, 0, len(slot_ids) - 1)]
    mesh_id = plm.add_subdiv_mesh(name, cage.positions, cage.face_sizes, cage.face_indices, cage.level,
                                  lightmap_uv=cage.uv if with_lightmap else None, material_ids=mat_ids,
                                  crease_edges=cage.crease_edges, crease_weights=cage.crease_weights,
                                  resolution=resolution)
    if cage.smooth:
        plm.set_mesh_smooth(mesh_id)
    return mesh_id
