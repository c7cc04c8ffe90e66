"""Objects made of analytic primitives and Boolean modifiers, exported as exact CSG solids.

An object marked with `object.photonlm.primitive` (made with Blender's add-primitive operators)
is the primitive's canonical shape (see the engine's photonlm.h) placed by the object's matrix
and sized from its mesh's bounds. Boolean modifiers (Union, Intersect, Difference, operand type
Object) whose operands are such objects, recursively, make the CSG tree. The object's evaluated
mesh (the Boolean result Blender shows) becomes the solid's carrier: it is not traced and its
lightmap shows the solid's light. Anything else raises NotExact with the reason, and the caller
bakes the mesh as usual.
"""
import mathutils
import numpy as np

from . import meshes

# Blender Boolean operation -> engine tree operator.
_OPS = {'UNION': "UNION", 'INTERSECT': "INTERSECTION", 'DIFFERENCE': "DIFFERENCE"}
# Modifiers that leave the primitive's shape as it is (display helpers, UV and data edits).
_HARMLESS = {'UV_PROJECT', 'UV_WARP', 'WEIGHTED_NORMAL', 'NORMAL_EDIT', 'DATA_TRANSFER', 'TRIANGULATE'}


class NotExact(Exception):
    """The object cannot be exported exactly; the message says why."""


def is_csg_object(obj):
    """Marked as a primitive, or carrying a Boolean modifier: worth trying to export exactly."""
    return obj.photonlm.primitive != 'NONE' or any(m.type == 'BOOLEAN' for m in obj.modifiers)


def _bounds(obj):
    """Local-space bounding box of the object's own (unmodified) mesh: (lo, hi)."""
    co = meshes.positions(obj.data).astype(np.float64)
    if not len(co):
        raise NotExact("object '%s' has an empty mesh" % obj.name)
    return co.min(axis=0), co.max(axis=0)


def _primitive(obj, material):
    """The engine primitive dict of a marked object: canonical shape, matrix, radii."""
    kind = obj.photonlm.primitive
    lo, hi = _bounds(obj)
    centre, half = (lo + hi) / 2.0, (hi - lo) / 2.0
    if np.any(half <= 0.0):
        raise NotExact("object '%s': its %s mesh is flat (bounds %s)" % (obj.name, kind.lower(), half))
    radii = {}
    if kind == 'SPHERE':
        if np.ptp(half) > 1e-4 * half.max():
            raise NotExact("object '%s': sphere mesh is not round (half sizes %s); scale the object instead"
                           % (obj.name, np.round(half, 6)))
        scale = half
    elif kind == 'BOX':
        scale = half
    elif kind in ('CYLINDER', 'CONE'):
        if abs(half[0] - half[1]) > 1e-4 * half.max():
            raise NotExact("object '%s': %s mesh is not round in x and y" % (obj.name, kind.lower()))
        scale = half
        if kind == 'CONE':  # the apex must be a point: no vertex off the axis at the top
            co = meshes.positions(obj.data).astype(np.float64)
            top = co[np.abs(co[:, 2] - hi[2]) < 1e-6 * max(half[2], 1e-12)]
            if len(top) and np.hypot(top[:, 0] - centre[0], top[:, 1] - centre[1]).max() > 1e-4 * half[0]:
                raise NotExact("object '%s': cone with a flat top (Radius 2 > 0) is not a primitive" % obj.name)
    elif kind == 'TORUS':
        minor = half[2]
        major = half[0] - minor
        if abs(half[0] - half[1]) > 1e-4 * half.max() or not major > minor:
            raise NotExact("object '%s': torus mesh with half sizes %s is not a torus about z"
                           % (obj.name, np.round(half, 6)))
        scale = np.ones(3)
        radii = dict(major_radius=float(major), minor_radius=float(minor))
    else:
        raise NotExact("object '%s': primitive type %s is not supported" % (obj.name, kind))
    local = mathutils.Matrix.Translation(mathutils.Vector(centre)) @ mathutils.Matrix.Diagonal(
        mathutils.Vector((scale[0], scale[1], scale[2], 1.0)))
    world = obj.matrix_world @ local
    return dict(shape=kind, matrix=np.array(world, np.float64), material=material, **radii)


def build_tree(obj, material_of, primitives, depth=0):
    """The CSG tree of obj (see the module doc), appending primitives; raises NotExact."""
    if depth > 32:
        raise NotExact("object '%s': Boolean operands nest more than 32 deep (a cycle?)" % obj.name)
    if obj.photonlm.primitive == 'NONE':
        raise NotExact("object '%s' is not marked as an analytic primitive (Active Object > Primitive)" % obj.name)
    primitives.append(_primitive(obj, material_of(obj)))
    tree = len(primitives) - 1
    for mod in obj.modifiers:
        if not mod.show_render:
            continue
        if mod.type in _HARMLESS:
            continue
        if mod.type != 'BOOLEAN':
            raise NotExact("object '%s': modifier '%s' (%s) changes the shape" % (obj.name, mod.name, mod.type))
        if mod.operand_type != 'OBJECT' or mod.object is None:
            raise NotExact("object '%s': Boolean modifier '%s' has no operand object" % (obj.name, mod.name))
        operand = build_tree(mod.object, material_of, primitives, depth + 1)
        tree = (_OPS[mod.operation], tree, operand)
    return tree


def export_csg(plm, obj, material_of):
    """Add obj's exact solid to the bridge scene; returns its id. Raises NotExact."""
    primitives = []
    tree = build_tree(obj, material_of, primitives)
    return plm.add_csg(obj.name, primitives, tree), len(primitives)
