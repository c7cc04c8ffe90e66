"""L-system objects after a bake: the light at each vertex of the preview mesh, from the object's
orientation lightmaps, in its point colour attribute LIGHT_ATTRIBUTE."""
import numpy as np

from ..export import meshes
from ..export.lsystem import LIGHT_ATTRIBUTE


def store_light(result, lsystem_id, obj):
    """Write the baked light at each preview vertex into the colour attribute LIGHT_ATTRIBUTE."""
    mesh = obj.data
    n = len(mesh.vertices)
    if n == 0:
        return
    mw = np.array(obj.matrix_world, np.float64)
    pts = meshes.world_positions(mesh, mw)
    nt = np.linalg.inv(mw[:3, :3]).T
    nw = meshes.vertex_normals(mesh) @ nt.T
    nw /= np.maximum(np.linalg.norm(nw, axis=1, keepdims=True), 1e-30)
    rgb = result.lsystem_lookup(lsystem_id, pts.astype(np.float32), nw.astype(np.float32))
    attr = mesh.color_attributes.get(LIGHT_ATTRIBUTE)
    if attr is None:
        attr = mesh.color_attributes.new(LIGHT_ATTRIBUTE, 'FLOAT_COLOR', 'POINT')
    rgba = np.concatenate([rgb, np.ones((n, 1), np.float32)], axis=1)
    attr.data.foreach_set("color", rgba.astype(np.float32).ravel())
    mesh.update()
