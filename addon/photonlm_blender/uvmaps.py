"""Creates the `lightmap` UV map of objects that have none.

The map is added to the ORIGINAL mesh (so it is saved with the file and survives
modifiers that keep UVs) and unwrapped with Smart UV Project, each object on its
own. Everything the user sees is restored afterwards: the active UV map (edit),
the active render UV map, the other UV maps' data, the mesh's selection and hide
flags, the object mode, the active object and the selection.
"""
import math

import bpy
import numpy as np

LIGHTMAP_UV = "lightmap"


def has_lightmap_uv(mesh):
    return LIGHTMAP_UV in mesh.uv_layers


def _get_flags(collection, attr):
    a = np.zeros(len(collection), dtype=bool)
    if len(collection):
        collection.foreach_get(attr, a)
    return a


def _set_flags(collection, attr, a):
    if len(collection):
        collection.foreach_set(attr, a)


def create_lightmap_uv(context, obj, resolution):
    """Add and unwrap a `lightmap` UV map on obj.data. Returns the new layer's name.

    The island margin is about two texels of the object's lightmap resolution.
    Raises RuntimeError if the mesh cannot take another UV map (Blender allows 8).
    """
    mesh = obj.data
    if len(mesh.uv_layers) >= 8:
        raise RuntimeError("mesh '%s' already has 8 UV maps; add a UV map named '%s' by hand"
                           % (mesh.name, LIGHTMAP_UV))
    old_active = mesh.uv_layers.active.name if mesh.uv_layers.active else None
    old_render = next((l.name for l in mesh.uv_layers if l.active_render), None)
    flags = {}
    for coll_name in ("vertices", "edges", "polygons"):
        coll = getattr(mesh, coll_name)
        flags[coll_name] = (_get_flags(coll, "select"), _get_flags(coll, "hide"))

    layer = mesh.uv_layers.new(name=LIGHTMAP_UV, do_init=False)
    if layer is None:
        raise RuntimeError("could not add a UV map to mesh '%s'" % mesh.name)
    name = layer.name
    mesh.uv_layers.active = mesh.uv_layers[name]

    view_layer = context.view_layer
    old_active_obj = view_layer.objects.active
    old_selected = [o for o in view_layer.objects if o.select_get()]
    margin = min(0.1, 2.0 / max(resolution, 16))
    try:
        for o in old_selected:
            o.select_set(False)
        obj.select_set(True)
        view_layer.objects.active = obj
        with context.temp_override(active_object=obj, object=obj,
                                   selected_objects=[obj], selected_editable_objects=[obj]):
            bpy.ops.object.mode_set(mode='EDIT')
            try:
                bpy.ops.mesh.reveal(select=False)
                bpy.ops.mesh.select_all(action='SELECT')
                with context.temp_override(edit_object=obj):
                    done = bpy.ops.uv.smart_project(angle_limit=math.radians(66.0), margin_method='FRACTION',
                                                    island_margin=margin, area_weight=0.0, correct_aspect=True,
                                                    scale_to_bounds=False)
                if done != {'FINISHED'}:
                    raise RuntimeError("Smart UV Project returned %s" % done)
            finally:
                bpy.ops.object.mode_set(mode='OBJECT')
    finally:
        obj.select_set(False)
        for o in old_selected:
            o.select_set(True)
        view_layer.objects.active = old_active_obj
        # Restore which UV maps are active (edit) and active for rendering, and the mesh flags.
        if old_active is not None and old_active in mesh.uv_layers:
            mesh.uv_layers.active = mesh.uv_layers[old_active]
        if old_render is not None and old_render in mesh.uv_layers:
            mesh.uv_layers[old_render].active_render = True
        for coll_name, (sel, hide) in flags.items():
            coll = getattr(mesh, coll_name)
            if len(coll) == len(sel):
                _set_flags(coll, "hide", hide)
                _set_flags(coll, "select", sel)
        mesh.update()
    return name


def tile_uv(mesh, name, index, tiles):
    """Squeeze UV map `name` into tile `index` of a tiles x tiles grid of the unit square. Objects
    combined by Boolean modifiers each get their own tile, so that the islands the Boolean result
    takes from its operands do not overlap."""
    layer = mesh.uv_layers.get(name)
    if layer is None or tiles <= 1:
        return
    uv = np.empty(len(layer.data) * 2, np.float32)
    layer.data.foreach_get("uv", uv)
    uv = uv.reshape(-1, 2)
    tx, ty = index % tiles, index // tiles
    uv = (uv + np.array([tx, ty], np.float32)) / float(tiles)
    layer.data.foreach_set("uv", uv.ravel())
    mesh.update()


def boolean_operands(obj, depth=0):
    """Mesh objects used as operands of obj's Boolean modifiers, recursively, in order."""
    out = []
    if depth > 32:
        return out
    for mod in obj.modifiers:
        if mod.type == 'BOOLEAN' and mod.operand_type == 'OBJECT' and mod.object is not None \
                and mod.object.type == 'MESH':
            out.append(mod.object)
            out += boolean_operands(mod.object, depth + 1)
    return out


def remove_uv(mesh, name):
    """Undo create_lightmap_uv (used when a bake is cancelled or fails)."""
    layer = mesh.uv_layers.get(name)
    if layer is not None:
        mesh.uv_layers.remove(layer)
