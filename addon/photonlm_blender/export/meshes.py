"""The mesh reader: every read of a Blender mesh's vertices, normals, UV maps and loop triangles
goes through here (foreach_get into numpy; nothing loops over vertices in Python).

Positions come back in object space as float32 (V, 3), or in world space as float64 (V, 3)
(positions @ M[:3, :3].T + M[:3, 3] in double precision); UVs per loop (L, 2) float32 or per
loop-triangle corner (T, 3, 2). Callers that want float32 world positions cast them.
"""
import contextlib

import numpy as np

from .. import compat

LIGHTMAP_UV = "lightmap"  # the UV map a lightmap is laid out in (uv/uvmaps.py makes it where the user has none)


@contextlib.contextmanager
def evaluated_mesh(obj, depsgraph):
    """The evaluated mesh of obj (modifiers applied) with loop triangles; freed on exit."""
    obj_eval = obj.evaluated_get(depsgraph)
    mesh = obj_eval.to_mesh()
    try:
        if mesh is not None:
            mesh.calc_loop_triangles()
        yield obj_eval, mesh
    finally:
        obj_eval.to_mesh_clear()


def positions(mesh):
    """Vertex positions in object space, (V, 3) float32."""
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    if len(co):
        mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def world_positions(mesh, matrix_world):
    """Vertex positions in world space, (V, 3) float64."""
    m = np.array(matrix_world, dtype=np.float64)
    return positions(mesh).astype(np.float64) @ m[:3, :3].T + m[:3, 3]


def vertex_normals(mesh):
    """Vertex normals in object space, (V, 3) float32."""
    nrm = np.empty(len(mesh.vertices) * 3, np.float32)
    if len(nrm):
        mesh.vertices.foreach_get("normal", nrm)
    return nrm.reshape(-1, 3)


def uv_layer(mesh, name=LIGHTMAP_UV):
    """The mesh's UV map `name`; None for the active render map; None where missing."""
    if name:
        return mesh.uv_layers.get(name)
    return next((l for l in mesh.uv_layers if l.active_render), None)


def loop_uv(layer, count):
    """A UV map's coordinates per loop, (count, 2) float32 (count: the mesh's loops)."""
    uv = np.empty(count * 2, np.float32)
    if len(uv):
        layer.data.foreach_get("uv", uv)
    return uv.reshape(-1, 2)


def lightmap_uv(mesh, name=LIGHTMAP_UV):
    """The map `name` per loop, (L, 2) float32, or None where the mesh has no such map."""
    layer = mesh.uv_layers.get(name)
    return None if layer is None else loop_uv(layer, len(mesh.loops))


def triangle_loops(mesh):
    """The loops of each loop-triangle corner, (T * 3,) int32 (the mesh has its loop triangles)."""
    loops = np.empty(len(mesh.loop_triangles) * 3, np.int32)
    if len(loops):
        mesh.loop_triangles.foreach_get("loops", loops)
    return loops


def triangle_vertices(mesh):
    """The vertices of each loop-triangle corner, (T * 3,) int32."""
    tv = np.empty(len(mesh.loop_triangles) * 3, np.int32)
    if len(tv):
        mesh.loop_triangles.foreach_get("vertices", tv)
    return tv


def triangle_values(mesh, attribute, dtype=np.int32):
    """A per-triangle attribute of the loop triangles (material_index, polygon_index), (T,)."""
    out = np.empty(len(mesh.loop_triangles), dtype)
    if len(out):
        mesh.loop_triangles.foreach_get(attribute, out)
    return out


def corner_uv(mesh, layer, loops=None):
    """A UV map per loop-triangle corner, (T, 3, 2) float32."""
    loops = triangle_loops(mesh) if loops is None else loops
    return loop_uv(layer, len(mesh.loops))[loops].reshape(len(mesh.loop_triangles), 3, 2)


def mesh_arrays(mesh, matrix_world, want_uv):
    """World-space positions (V,3) f32, triangles (T,3) u32, material indices (T,) i32 and the
    lightmap UV per triangle corner (T,3,2) f32 (None if not wanted or missing)."""
    nt = len(mesh.loop_triangles)
    pos = world_positions(mesh, matrix_world).astype(np.float32)
    tris = triangle_vertices(mesh)
    mat_index = triangle_values(mesh, "material_index")
    uv = None
    layer = mesh.uv_layers.get(LIGHTMAP_UV)
    if want_uv and layer is not None:
        uv = corner_uv(mesh, layer)
    return pos, tris.reshape(nt, 3).astype(np.uint32), mat_index, uv


def shading_normals(mesh, matrix_world):
    """World-space shading normals per triangle corner (T, 3, 3) float32 for the smooth faces
    (their split normals: smooth shading, Auto Smooth, custom normals), (0, 0, 0) on flat faces
    (the engine then shades with the triangle's own normal); None when every face is flat."""
    npoly, nt = len(mesh.polygons), len(mesh.loop_triangles)
    smooth = np.zeros(npoly, dtype=bool)
    if npoly:
        mesh.polygons.foreach_get("use_smooth", smooth)
    if not smooth.any():
        return None
    n = compat.corner_normals(mesh).reshape(nt, 3, 3).astype(np.float64)
    poly = triangle_values(mesh, "polygon_index")
    # Normals transform with the inverse transpose of the object's linear part.
    m = np.array(matrix_world, dtype=np.float64)[:3, :3]
    try:
        normal_matrix = np.linalg.inv(m).T
    except np.linalg.LinAlgError:
        return None  # a flattened object: no direction to shade with
    n = n @ normal_matrix.T
    n[~smooth[poly]] = 0.0
    return n.astype(np.float32)


def world_triangles(mesh, matrix):
    """World positions of the loop-triangle corners (T, 3, 3) float64, the triangle count and the
    corners' vertices (T * 3,). Computes the loop triangles."""
    mesh.calc_loop_triangles()
    nt = len(mesh.loop_triangles)
    tv = triangle_vertices(mesh)
    return world_positions(mesh, matrix)[tv].reshape(nt, 3, 3), nt, tv


def surface_area(pos, tris):
    """Area of triangles (T, 3) over positions (V, 3)."""
    if len(tris) == 0:
        return 0.0
    p = pos.astype(np.float64)
    a, b, c = p[tris[:, 0]], p[tris[:, 1]], p[tris[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    return float(np.nansum(area[np.isfinite(area)]))
