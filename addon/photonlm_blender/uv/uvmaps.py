"""Lightmap UV maps: the user's own, or made for the mesh as its modifiers leave it.

A UV map named `lightmap` that the user made (one with some UV area that this module did not
make) is baked as it is. Every other object that gets a lightmap gets an automatic map, made
for its *evaluated* mesh -- the mesh after all its modifiers, or, when its last modifier is a
Subdivision Surface the engine refines itself (subdiv.py), the cage before that
modifier -- so that Solidify shells, Array and Mirror copies, Bevels and the faces a Boolean
takes from its operands each get their own texels.

How a map is made (_unwrap): a copy of the evaluated mesh is split into charts by Smart UV
Project (66 degrees), each chart is unwrapped again with ABF (angle based, from the limit surface
for a cage) and the islands are packed with a gap of 2.2 texels at the object's lightmap
resolution. The result is measured as the engine will use it (uvcheck.py; a cage after the
engine's own refinement at the levels it is baked at): faces of triangles that lie outside the
square, fold, overlap or are concave quads after subdivision are cut out as islands of their own
and the mesh is unwrapped again (a single cage face always stays valid under subdivision).
A cage that still fails after a few rounds is given up: the map is made for Blender's
subdivided mesh instead, and the object is baked as that mesh.

Where the map lives:
- in the mesh itself, when the evaluated mesh has the mesh's own topology (no modifiers, or only
  ones that move vertices; a subdivision cage without earlier modifiers): the mesh's `lightmap`
  UV map holds it, and the custom property `photonlm_lightmap_uv` records that it is automatic
  (the topology and UV hash it was made for) so that a later bake can tell it from one the user
  has edited since;
- otherwise in a helper object 'PhotonLM UV <object>' (an unwrapped copy of the evaluated mesh,
  in no scene, kept by a fake user), copied onto the evaluated mesh by a Data Transfer modifier
  'PhotonLM Lightmap UV' (face corner UVs, topology mapping) at the end of the object's stack
  or just before its last Subdivision Surface. Data Transfer only writes into an existing UV
  map, so the mesh gets an empty `lightmap` map for it to fill. The modifier is what marks the
  object's map as automatic. Because the evaluated mesh carries a real UV map, Cycles, EEVEE
  (the preview's UV Map node), the exporter and the subdivision cage reader all see it, in the
  saved file too.

A second bake reuses a map while the evaluated mesh (topology and positions) and the lightmap
resolution are the ones it was made for. ensure_lightmap_uvs returns a Changes list: undo()
restores everything it changed (a cancelled or failed bake), commit() removes helper objects
no modifier uses any more.
"""
import hashlib
import math
import re
import time

import bpy
import numpy as np

from .. import bridge
from ..export import meshes, subdiv
from ..export.meshes import LIGHTMAP_UV
from ..export.resolution import ResolutionRule
from . import uvcheck

MODIFIER_NAME = "PhotonLM Lightmap UV"
ATLAS_MODIFIER_NAME = "PhotonLM Atlas UV"   # writeback/atlas.py's UV Warp: not a modifier of the user's
HELPER_PREFIX = "PhotonLM UV "
HELPER_TAG = "photonlm_lightmap_uv_helper"   # on helper objects: a dict describing the map
MESH_TAG = "photonlm_lightmap_uv"            # on meshes holding an automatic map themselves
MARGIN_TEXELS = 2.2     # gap between islands packed by Blender (2 texels required, a little to spare)
ROUNDS = 4              # unwraps per object before giving up
VERSION = 1             # bump when the way maps are made changes: older maps are made again

CAGE, FULL = "cage", "full"


def has_lightmap_uv(mesh):
    return LIGHTMAP_UV in mesh.uv_layers


# ---- what an object has ---------------------------------------------------------------------------

def automatic_modifier(obj):
    """The object's Data Transfer modifier that carries its automatic map, or None."""
    for mod in getattr(obj, "modifiers", ()):
        if mod.type == 'DATA_TRANSFER' and mod.name.startswith(MODIFIER_NAME) and \
                mod.object is not None and mod.object.get(HELPER_TAG) is not None:
            return mod
    return None


def user_modifiers(obj):
    """The object's modifiers other than the automatic map's and the atlas placement's (writeback/atlas.py)."""
    ours = automatic_modifier(obj)
    return [m for m in obj.modifiers if m != ours and not is_atlas_modifier(m)]


def is_atlas_modifier(mod):
    """The UV Warp modifier that moves an object's atlas UV map into its block (writeback/atlas.py)."""
    return mod.type == 'UV_WARP' and mod.name.startswith(ATLAS_MODIFIER_NAME)


def _layer_uv(mesh):
    """The lightmap map per loop, flat (L * 2,) float32; None where the mesh has none."""
    uv = meshes.lightmap_uv(mesh)
    return None if uv is None else uv.reshape(-1)


def _digest(*arrays):
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str(a.dtype).encode() + str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _topology(mesh):
    """Loop vertex indices and polygon sizes of a mesh (what decides the face corner order)."""
    lv = np.empty(len(mesh.loops), np.int32)
    if len(lv):
        mesh.loops.foreach_get("vertex_index", lv)
    sizes = np.empty(len(mesh.polygons), np.int32)
    if len(sizes):
        mesh.polygons.foreach_get("loop_total", sizes)
    return lv, sizes


def _fingerprint(mesh):
    """A digest of a mesh's topology and vertex positions."""
    co = meshes.positions(mesh).reshape(-1)
    lv, sizes = _topology(mesh)
    return _digest(np.array([len(mesh.vertices), VERSION]), lv, sizes, co)


def _has_area(uv):
    """True when a map spreads over some area (a placeholder map is all zeros)."""
    if uv is None or not len(uv):
        return False
    p = uv.reshape(-1, 2)
    if not np.isfinite(p).all():
        return True
    return bool(np.ptp(p[:, 0]) > 0 and np.ptp(p[:, 1]) > 0)


def kind(obj):
    """'user' (the mesh has a `lightmap` map the user made), 'automatic' (one this module made)
    or None (none yet)."""
    mesh = obj.data
    if automatic_modifier(obj) is not None:
        return 'automatic'
    uv = _layer_uv(mesh)
    if uv is None:
        return None
    tag = mesh.get(MESH_TAG)
    if tag is not None:
        lv, sizes = _topology(mesh)
        if tag.get("uv") == _digest(uv) or tag.get("topology") != _digest(lv, sizes):
            return 'automatic'  # unchanged, or its mesh was remodelled (the map was not edited)
    return 'user' if _has_area(uv) else None


def status(obj):
    """A short line for the panel (cheap: no hashing): whose `lightmap` UV map the object has."""
    mesh = getattr(obj, "data", None)
    if mesh is None or not hasattr(mesh, "uv_layers"):
        return "", 'UV'
    if automatic_modifier(obj) is not None or (LIGHTMAP_UV in mesh.uv_layers and mesh.get(MESH_TAG) is not None):
        return "UV map 'lightmap': automatic (made for the evaluated mesh)", 'CHECKMARK'
    if LIGHTMAP_UV in mesh.uv_layers:
        return "UV map 'lightmap': yours (used as it is)", 'CHECKMARK'
    return "UV map 'lightmap': made when baking", 'UV'


# ---- undo -----------------------------------------------------------------------------------------------

class Changes(list):
    """What ensure_lightmap_uvs changed, newest last: callables that undo one change each."""

    def __init__(self):
        super().__init__()
        self.made = []          # (object name, how): 'mesh', 'transfer' or 'reused'

    def undo(self):
        for fn in reversed(self):
            try:
                fn()
            except Exception:  # noqa: BLE001 -- the data was removed meanwhile: undo the rest
                pass
        self.clear()

    def commit(self):
        """Keep the changes; remove helper objects that no Data Transfer modifier uses any more."""
        used = {m.object.name for o in bpy.data.objects for m in getattr(o, "modifiers", ())
                if m.type == 'DATA_TRANSFER' and m.object is not None}
        for helper in [o for o in bpy.data.objects if o.get(HELPER_TAG) is not None and o.name not in used]:
            mesh = helper.data
            bpy.data.objects.remove(helper)
            _remove_if_unused(mesh)
        self.clear()


def undo(changes):
    """Undo what ensure_lightmap_uvs did (a list of (mesh, name) from older code is accepted too)."""
    if isinstance(changes, Changes):
        changes.undo()
        return
    for mesh, name in changes or ():
        remove_uv(mesh, name)


def commit(changes):
    if isinstance(changes, Changes):
        changes.commit()


def remove_uv(mesh, name):
    layer = mesh.uv_layers.get(name)
    if layer is not None:
        mesh.uv_layers.remove(layer)


# ---- evaluating ---------------------------------------------------------------------------------------

def cage_subsurf(obj, native_subdivision):
    """The last (user) modifier when the engine refines the object from its cage, else None."""
    mods = user_modifiers(obj)
    if not native_subdivision or not mods or mods[-1].type != 'SUBSURF':
        return None
    mod = mods[-1]
    if mod.render_levels < 1 or subdiv.unsupported_reason(obj, mod) is not None:
        return None
    return mod


def _remove_if_unused(mesh):
    """Remove a mesh from bpy.data once nothing uses it (a helper's or an evaluated copy's)."""
    if mesh is not None and mesh.users == 0:
        bpy.data.meshes.remove(mesh)


def _copies(context, requests):
    """{(object name, stage): a new mesh in bpy.data}: each object's evaluated mesh (modifiers as the
    viewport shows them) at the stage asked for, for CAGE without its last Subdivision Surface
    (whose viewport switch is turned off for a moment and restored)."""
    out = {}

    def copy_all(stage, depsgraph):
        for obj, st in requests:
            if st == stage:
                ev = obj.evaluated_get(depsgraph)
                mesh = bpy.data.meshes.new_from_object(ev, preserve_all_data_layers=False, depsgraph=depsgraph)
                mesh.name = HELPER_PREFIX + obj.name
                out[(obj.name, stage)] = mesh
    # A cage whose Subdivision Surface is the object's only modifier, without shape keys, is its own
    # mesh: copied as it is, without switching the modifier off (which would evaluate the object twice).
    direct = [(obj, st) for obj, st in requests
              if st == CAGE and len(obj.modifiers) == 1 and obj.data.shape_keys is None]
    for obj, st in direct:
        mesh = obj.data.copy()
        mesh.name = HELPER_PREFIX + obj.name
        out[(obj.name, st)] = mesh
    requests = [r for r in requests if r not in direct]
    if any(st == CAGE for _, st in requests):
        toggled = []
        try:
            for obj, st in requests:
                mod = user_modifiers(obj)[-1] if st == CAGE else None
                if mod is not None and mod.show_viewport:
                    mod.show_viewport = False
                    toggled.append(mod)
            copy_all(CAGE, context.evaluated_depsgraph_get())
        finally:
            for mod in toggled:
                mod.show_viewport = True
    if any(st == FULL for _, st in requests):
        copy_all(FULL, context.evaluated_depsgraph_get())
    return out


def _strip(mesh):
    """Leave the geometry only: no UV maps but an empty `lightmap`, no materials, no seams."""
    while len(mesh.uv_layers):
        mesh.uv_layers.remove(mesh.uv_layers[0])
    mesh.materials.clear()
    if len(mesh.edges):
        mesh.edges.foreach_set("use_seam", np.zeros(len(mesh.edges), bool))
    layer = mesh.uv_layers.new(name=LIGHTMAP_UV, do_init=False)
    layer.data.foreach_set("uv", np.zeros(len(mesh.loops) * 2, np.float32))


def _triangles(mesh, matrix):
    """World positions (T, 3, 3) and lightmap UVs (T, 3, 2) of a mesh's loop triangles."""
    pos, nt, _ = meshes.world_triangles(mesh, matrix)
    tl = meshes.triangle_loops(mesh)
    tp = meshes.triangle_values(mesh, "polygon_index")
    uv = _layer_uv(mesh).reshape(-1, 2)
    return pos, uv[tl].reshape(nt, 3, 2), tp


def triangle_area(mesh, matrix):
    """World-space surface area of a mesh (the exporter's measure, for the lightmap resolution)."""
    p, nt, _ = meshes.world_triangles(mesh, matrix)
    if nt == 0:
        return 0.0
    a = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    return float(np.nansum(a[np.isfinite(a)]))


# ---- unwrapping ------------------------------------------------------------------------------------------

class Result:
    """An unwrapped copy: its UV per loop, how it measures and what it took."""

    def __init__(self, uv, stats, rounds, seconds):
        self.uv = uv
        self.stats = stats
        self.rounds = rounds
        self.seconds = seconds

    @property
    def clean(self):
        return uvcheck.clean(self.stats)


def _check_flat(mesh, matrix, res):
    """Measure the copy's map as it is exported (Blender's triangles): stats and the bad polygons."""
    pos, uv, poly = _triangles(mesh, matrix)
    stats = uvcheck.analyse(uv, res, pos)
    if uvcheck.clean(stats):
        return stats, np.zeros(0, np.int64)
    bad = uvcheck.bad_triangles(uv, res, pos)
    return stats, np.unique(poly[bad])


def _check_cage(mesh, matrix, res, levels, use_creases):
    """Measure a cage's map after the engine's refinement at each of levels: the worst stats and
    the cage faces whose refined triangles are bad."""
    photonlm = bridge.get()
    worst, bad_faces = None, set()
    cage = subdiv.read_cage(mesh, matrix, max(levels), use_creases)
    for level in levels:
        pos, tri, uv = photonlm.subdiv_refine(cage.positions, cage.face_sizes, cage.face_indices, level,
                                              lightmap_uv=cage.uv, crease_edges=cage.crease_edges,
                                              crease_weights=cage.crease_weights)
        p = pos[tri.astype(np.int64)]
        stats = uvcheck.analyse(uv, res, p)
        bad = uvcheck.bad_triangles(uv, res, p, quads=True)  # concave quads too: any split must be valid
        stats["concave_quads"] = int(bad.any() and uvcheck.clean(stats))  # bad, yet clean: concave quads
        per_face = cage.face_sizes.astype(np.int64) * 2 * 4 ** (level - 1)
        face_of = np.repeat(np.arange(len(cage.face_sizes)), per_face)
        if len(face_of) == len(bad):
            bad_faces |= set(np.unique(face_of[bad]).tolist())
        elif bad.any():
            bad_faces |= set(range(len(cage.face_sizes)))
        if worst is None or _badness(stats) > _badness(worst):
            worst = stats
    return worst, np.array(sorted(bad_faces), np.int64)


def _badness(stats):
    return (stats["overlap_texels"] + stats["shared_texels"] + stats["zero_area"] + stats["outside"]
            + stats["flipped"] + stats.get("concave_quads", 0) + (stats["margin"] < 2.0))


def _unwrap(context, mesh, matrix, res, subsurf=None, levels=()):
    """Unwrap mesh (a stripped copy) into its `lightmap` map for a res x res lightmap. With a
    Subdivision Surface modifier `subsurf`, mesh is its cage and the map is measured after the
    refinement at each of levels. Returns the best Result."""
    t0 = time.perf_counter()
    margin = MARGIN_TEXELS / 2.0 / res  # Blender leaves 2 x margin between islands
    obj = bpy.data.objects.new(mesh.name, mesh)
    obj.matrix_world = matrix
    if subsurf is not None:
        mod = obj.modifiers.new("Subdivision", 'SUBSURF')
        for attr in ("subdivision_type", "use_limit_surface", "quality", "boundary_smooth", "uv_smooth",
                     "use_creases", "use_custom_normals"):
            if hasattr(subsurf, attr):
                setattr(mod, attr, getattr(subsurf, attr))
        mod.levels = max(levels) if levels else subsurf.levels
    context.scene.collection.objects.link(obj)
    view_layer = context.view_layer
    best = None
    try:
        with context.temp_override(active_object=obj, object=obj, edit_object=obj, selected_objects=[obj],
                                   selected_editable_objects=[obj]):
            for rnd in range(ROUNDS):
                view_layer.objects.active = obj
                obj.select_set(True)
                bpy.ops.object.mode_set(mode='EDIT')
                try:
                    bpy.ops.mesh.reveal(select=False)
                    bpy.ops.mesh.select_all(action='SELECT')
                    if rnd == 0:
                        bpy.ops.uv.smart_project(angle_limit=math.radians(66.0), margin_method='FRACTION',
                                                 island_margin=margin, area_weight=0.0, correct_aspect=True,
                                                 scale_to_bounds=False)
                        bpy.ops.uv.select_all(action='SELECT')
                        bpy.ops.uv.seams_from_islands(mark_seams=True, mark_sharp=False)
                    bpy.ops.uv.unwrap(method='ANGLE_BASED', fill_holes=True, correct_aspect=True,
                                      use_subsurf_data=subsurf is not None, margin_method='FRACTION',
                                      margin=margin)
                finally:
                    bpy.ops.object.mode_set(mode='OBJECT')
                if subsurf is not None:
                    stats, bad = _check_cage(mesh, matrix, res, levels, subsurf.use_creases)
                else:
                    stats, bad = _check_flat(mesh, matrix, res)
                uv = _layer_uv(mesh)
                if best is None or _badness(stats) < _badness(best.stats):
                    best = Result(uv, stats, rnd + 1, 0.0)
                if uvcheck.clean(stats) or not len(bad):
                    break
                # Cut the faces that went wrong out as islands of their own, unwrap again.
                edge_of_loop = np.empty(len(mesh.loops), np.int32)
                mesh.loops.foreach_get("edge_index", edge_of_loop)
                starts = np.empty(len(mesh.polygons), np.int32)
                mesh.polygons.foreach_get("loop_start", starts)
                sizes = np.empty(len(mesh.polygons), np.int32)
                mesh.polygons.foreach_get("loop_total", sizes)
                bad_starts, bad_sizes = starts[np.asarray(bad)].astype(np.int64), sizes[np.asarray(bad)]
                first = np.cumsum(bad_sizes, dtype=np.int64) - bad_sizes
                loops = np.repeat(bad_starts - first, bad_sizes) + np.arange(int(bad_sizes.sum()))
                seams = np.empty(len(mesh.edges), bool)
                mesh.edges.foreach_get("use_seam", seams)
                seams[edge_of_loop[loops]] = True
                mesh.edges.foreach_set("use_seam", seams)
    finally:
        bpy.data.objects.remove(obj)
    best.seconds = time.perf_counter() - t0
    layer = mesh.uv_layers[LIGHTMAP_UV]
    layer.data.foreach_set("uv", best.uv)
    return best


# ---- putting a map in place --------------------------------------------------------------------------

def _placeholder(mesh, changes):
    """Make sure the mesh has a `lightmap` UV map (Data Transfer's destination) without changing
    which UV maps are active. Raises RuntimeError when it cannot."""
    if LIGHTMAP_UV in mesh.uv_layers:
        return
    if len(mesh.uv_layers) >= 8:
        raise RuntimeError("mesh '%s' already has 8 UV maps; add a UV map named '%s' by hand"
                           % (mesh.name, LIGHTMAP_UV))
    active = mesh.uv_layers.active.name if mesh.uv_layers.active else None
    render = next((l.name for l in mesh.uv_layers if l.active_render), None)
    layer = mesh.uv_layers.new(name=LIGHTMAP_UV, do_init=False)
    if layer is None:
        raise RuntimeError("could not add a UV map to mesh '%s'" % mesh.name)
    layer.data.foreach_set("uv", np.zeros(len(mesh.loops) * 2, np.float32))
    if active is not None:
        mesh.uv_layers.active = mesh.uv_layers[active]
    if render is not None:
        mesh.uv_layers[render].active_render = True
    changes.append(lambda: remove_uv(mesh, LIGHTMAP_UV))


def _write_into_mesh(mesh, uv, changes, tag):
    """Store an automatic map in the mesh's own `lightmap` UV map and tag the mesh with it."""
    _placeholder(mesh, changes)
    old_uv, old_tag = _layer_uv(mesh), mesh.get(MESH_TAG)
    old_tag = old_tag.to_dict() if old_tag is not None else None

    def restore():
        layer = mesh.uv_layers.get(LIGHTMAP_UV)
        if layer is not None and len(old_uv) == len(mesh.loops) * 2:
            layer.data.foreach_set("uv", old_uv)
        if old_tag is None:
            mesh.pop(MESH_TAG, None)
        else:
            mesh[MESH_TAG] = old_tag
    changes.append(restore)
    mesh.uv_layers[LIGHTMAP_UV].data.foreach_set("uv", uv)
    lv, sizes = _topology(mesh)
    mesh[MESH_TAG] = dict(tag, uv=_digest(uv), topology=_digest(lv, sizes), version=VERSION)
    mesh.update()


def _modifier_index(obj, stage):
    n = len(user_modifiers(obj))
    return n - 1 if stage == CAGE else n


def move_modifier(obj, mod, index):
    if list(obj.modifiers).index(mod) == index:
        return
    active = obj.modifiers.active
    with bpy.context.temp_override(object=obj, active_object=obj):
        bpy.ops.object.modifier_move_to_index(modifier=mod.name, index=index)
    if active is not None:
        obj.modifiers.active = active


def _transfer(obj, helper, stage, changes):
    """Point the object's Data Transfer modifier at helper, at the stage's place in its stack."""
    _placeholder(obj.data, changes)
    mod = automatic_modifier(obj)
    active = obj.modifiers.active
    if mod is None:
        mod = obj.modifiers.new(MODIFIER_NAME, 'DATA_TRANSFER')
        name = mod.name
        changes.append(lambda: obj.modifiers.remove(obj.modifiers[name]) if name in obj.modifiers else None)
        if active is not None:
            obj.modifiers.active = active  # the user's active modifier stays active
    else:
        old_object, old_index, name = mod.object, list(obj.modifiers).index(mod), mod.name

        def restore():
            m = obj.modifiers.get(name)
            if m is not None:
                m.object = old_object
                move_modifier(obj, m, old_index)
        changes.append(restore)
    # Moved before it points at the helper: the move evaluates the object, and a Data Transfer at
    # another place in the stack than the helper's copy reports a topology mismatch.
    mod.object = helper  # what marks it as ours for _modifier_index
    index = _modifier_index(obj, stage)
    mod.object = None
    move_modifier(obj, mod, index)
    mod.use_object_transform = False
    mod.use_loop_data = True
    mod.data_types_loops = {'UV'}
    mod.loop_mapping = 'TOPOLOGY'
    mod.layers_uv_select_src = 'ALL'
    mod.layers_uv_select_dst = 'NAME'
    mod.mix_mode = 'REPLACE'
    mod.mix_factor = 1.0
    mod.show_in_editmode = False
    mod.show_expanded = False
    mod.object = helper


def _new_helper(obj, mesh, changes, tag):
    """The object holding an unwrapped copy for Data Transfer: in no scene, kept by a fake user."""
    helper = bpy.data.objects.new(HELPER_PREFIX + obj.name, mesh)
    helper.use_fake_user = True
    helper.hide_render = True
    helper[HELPER_TAG] = dict(tag, version=VERSION)
    name = helper.name

    def remove():
        h = bpy.data.objects.get(name)
        if h is not None:
            m = h.data
            bpy.data.objects.remove(h)
            _remove_if_unused(m)
    changes.append(remove)
    return helper


# ---- the whole step -----------------------------------------------------------------------------------------

def _stage_now(obj):
    """Where the object's automatic map sits now: (stage, fingerprint, resolution, modifier, helper tag)
    or None when it has no Data Transfer modifier of ours."""
    mod = automatic_modifier(obj)
    if mod is None:
        return None
    tag = mod.object.get(HELPER_TAG)
    return tag.get("stage"), tag.get("fingerprint"), tag.get("resolution"), mod, tag


def ensure_lightmap_uvs(context, objects, reports, resolution_of, native_subdivision=True):
    """Make or refresh the automatic lightmap UV maps of `objects` (see the module doc).
    resolution_of(obj, area) gives an object's lightmap size from its world-space area (a number,
    or a function giving it).
    Returns a Changes list. Must run in Object Mode; the selection and active object are kept."""
    changes = Changes()
    todo = []
    for obj in objects:
        mesh = obj.data
        if kind(obj) == 'user':
            continue
        if mesh.library is not None or getattr(mesh, "override_library", None) is not None:
            reports.warning("object '%s': mesh '%s' is linked from a library and has no '%s' UV map: "
                            "baked as geometry only" % (obj.name, mesh.name, LIGHTMAP_UV))
            continue
        todo.append(obj)
    if not todo:
        return changes
    view_layer = context.view_layer
    old_active = view_layer.objects.active
    old_selected = [o for o in view_layer.objects if o.select_get()]
    if old_active is not None and old_active.mode != 'OBJECT':
        raise RuntimeError("lightmap UVs are made in Object Mode")
    try:
        for o in old_selected:
            o.select_set(False)
        _ensure(context, todo, reports, resolution_of, native_subdivision, changes)
    finally:
        for o in view_layer.objects:
            o.select_set(False)
        for o in old_selected:
            try:
                o.select_set(True)
            except (ReferenceError, RuntimeError):
                pass
        view_layer.objects.active = old_active
    return changes


def _ensure(context, todo, reports, resolution_of, native_subdivision, changes):
    cage_objs = {o.name for o in todo if cage_subsurf(o, native_subdivision) is not None}

    def fell_back(o):
        now = _stage_now(o)
        return now[4] if now is not None and now[0] == FULL and now[4].get("cage_fingerprint") else None

    requests = [(o, CAGE if o.name in cage_objs else FULL) for o in todo]
    requests += [(o, FULL) for o in todo if o.name in cage_objs and fell_back(o) is not None]
    shared = {}     # (stage, fingerprint, resolution) -> ('mesh', mesh name, uv) or ('helper', helper object, None)
    made = []       # objects whose map is in place
    retry = []
    copies = _copies(context, requests)
    try:
        for obj in todo:
            if obj.name in cage_objs:
                cage_fp = _fingerprint(copies[(obj.name, CAGE)])
                tag = fell_back(obj)
                if tag is not None and tag.get("cage_fingerprint") == cage_fp:
                    outcome = _make_one(context, obj, copies.pop((obj.name, FULL)), FULL, resolution_of,
                                        changes, reports, shared, str(tag.get("fallback", "")), cage_fp)
                else:
                    outcome = _make_one(context, obj, copies.pop((obj.name, CAGE)), CAGE, resolution_of,
                                        changes, reports, shared)
                    if isinstance(outcome, tuple):  # ('retry', why): make it for Blender's subdivided mesh
                        retry.append((obj, cage_fp, outcome[1]))
                        continue
            else:
                outcome = _make_one(context, obj, copies.pop((obj.name, FULL)), FULL, resolution_of,
                                    changes, reports, shared)
            if outcome is not None:
                made.append(obj)
    finally:
        for mesh in copies.values():
            _remove_if_unused(mesh)
    if retry:
        copies = _copies(context, [(o, FULL) for o, _, _ in retry])
        try:
            for obj, cage_fp, why in retry:
                if _make_one(context, obj, copies.pop((obj.name, FULL)), FULL, resolution_of, changes,
                             reports, shared, why, cage_fp) is not None:
                    made.append(obj)
        finally:
            for mesh in copies.values():
                _remove_if_unused(mesh)
    if changes:
        context.view_layer.update()
    _verify(context, made, reports)


def _resolution(obj, copy, stage, resolution_of):
    """The lightmap size the exporter will give obj: from the cage's area for a cage the engine
    refines (subdiv.py), else from the evaluated mesh's triangles."""
    m = np.array(obj.matrix_world, np.float64)
    if stage == CAGE:
        pa = np.empty(len(copy.polygons), np.float32)
        copy.polygons.foreach_get("area", pa)
        return resolution_of(obj, float(pa.sum()) * abs(np.linalg.det(m[:3, :3])) ** (2.0 / 3.0))
    return resolution_of(obj, lambda: triangle_area(copy, m))  # measured only for an Auto resolution


def _make_one(context, obj, copy, stage, resolution_of, changes, reports, shared, why_full=None,
              cage_fp=None):
    """Reuse, make or refresh obj's automatic map from `copy` (its evaluated mesh at `stage`, which this
    function owns). Returns 'reused', 'mesh', 'transfer', ('retry', why) (a cage that cannot keep a
    map: make it for the full mesh) or None (no map)."""
    mesh = obj.data
    res = _resolution(obj, copy, stage, resolution_of)
    fingerprint = _fingerprint(copy)
    lv_copy, sizes_copy = _topology(copy)
    lv_mesh, sizes_mesh = _topology(mesh)
    same_topology = np.array_equal(lv_copy, lv_mesh) and np.array_equal(sizes_copy, sizes_mesh)
    now = _stage_now(obj)
    key = (stage, fingerprint, res)

    # Reuse a map made for this mesh, stage and resolution: by an earlier bake, or just now for a copy.
    if now is not None:
        st, fp, r, mod, _tag = now
        if (st, fp, r) == key and list(obj.modifiers).index(mod) == _modifier_index(obj, stage) \
                and LIGHTMAP_UV in mesh.uv_layers:
            _remove_if_unused(copy)
            changes.made.append((obj.name, 'reused'))
            return 'reused'
    else:
        tag = mesh.get(MESH_TAG)
        if tag is not None and same_topology and (tag.get("stage"), tag.get("fingerprint"), tag.get("resolution")) \
                == key and tag.get("uv") == _digest(_layer_uv(mesh)):
            _remove_if_unused(copy)
            changes.made.append((obj.name, 'reused'))
            return 'reused'
    writable = same_topology and now is None and not any(w == 'mesh' and n == mesh.name for w, n, _ in shared.values())
    if key in shared:
        where, what, uv = shared[key]
        if where == 'mesh' and what == mesh.name and now is None and same_topology:
            _remove_if_unused(copy)
            changes.made.append((obj.name, 'reused'))
            return 'reused'
        if where == 'mesh' and writable:  # another mesh with the same geometry: the same map
            _write_into_mesh(mesh, uv, changes, dict(stage=stage, fingerprint=fingerprint, resolution=res))
            _remove_if_unused(copy)
            shared[key] = ('mesh', mesh.name, uv)
            changes.made.append((obj.name, 'reused'))
            return 'reused'
        if where == 'helper':
            _remove_if_unused(copy)
            _transfer(obj, what, stage, changes)
            changes.made.append((obj.name, 'reused'))
            return 'reused'
    _strip(copy)
    if len(copy.polygons) == 0:
        _remove_if_unused(copy)
        reports.warning("object '%s': its evaluated mesh has no faces: no lightmap UV map" % obj.name)
        return None
    subsurf = user_modifiers(obj)[-1] if stage == CAGE else None
    levels = sorted({subsurf.render_levels} | ({subsurf.levels} if subsurf.levels > 0 else set())) \
        if subsurf is not None else ()
    try:
        result = _unwrap(context, copy, obj.matrix_world, res, subsurf, levels)
    except NotImplementedError as e:  # a cage the engine does not refine (subdiv._read_cage)
        _remove_if_unused(copy)
        return ('retry', str(e))
    except Exception as e:  # noqa: BLE001 -- an add-on must not take Blender down
        _remove_if_unused(copy)
        reports.warning("object '%s': could not make a lightmap UV map (%s): baked as geometry only" % (obj.name, e))
        return None
    if stage == CAGE and not result.clean:
        _remove_if_unused(copy)
        return ('retry', "its lightmap UV map does not stay valid under subdivision (%s after %d unwraps)"
                % (uvcheck.describe(result.stats), result.rounds))
    stats = result.stats
    how = ("for its subdivision cage (refined by the engine)" if stage == CAGE else
           "for its mesh after modifiers" if user_modifiers(obj) else "for its mesh")
    if why_full:
        how += " (%s: Blender's subdivided mesh is baked)" % why_full
    if result.clean:
        reports.info("object '%s': lightmap UV map made %s (%d x %d: %d islands at least %.1f texels apart, "
                     "%.0f %% of the map used)" % (obj.name, how, res, res, stats["islands"], stats["margin"],
                                                    100 * stats["utilisation"]))
    else:
        reports.warning("object '%s': lightmap UV map made %s is not clean at %d x %d: %s"
                        % (obj.name, how, res, res, uvcheck.describe(stats)))
    try:
        if writable:
            _write_into_mesh(mesh, result.uv, changes, dict(stage=stage, fingerprint=fingerprint, resolution=res))
            _remove_if_unused(copy)
            shared[key] = ('mesh', mesh.name, result.uv)
            changes.made.append((obj.name, 'mesh'))
            return 'mesh'
        helper = _new_helper(obj, copy, changes, dict(stage=stage, fingerprint=fingerprint, resolution=res,
                                                      rounds=result.rounds))
        if why_full:
            helper[HELPER_TAG]["fallback"] = why_full
            helper[HELPER_TAG]["cage_fingerprint"] = cage_fp or ""
        _transfer(obj, helper, stage, changes)
        shared[key] = ('helper', helper, None)
        changes.made.append((obj.name, 'transfer'))
        return 'transfer'
    except Exception as e:  # noqa: BLE001
        _remove_if_unused(copy)
        reports.warning("object '%s': could not store its lightmap UV map (%s): baked as geometry only"
                        % (obj.name, e))
        return None


def _verify(context, objects, reports):
    """Check that the evaluated meshes now carry the maps (a modifier after ours may drop UV maps)."""
    depsgraph = context.evaluated_depsgraph_get()
    for obj in objects:
        ev = obj.evaluated_get(depsgraph)
        mesh = ev.to_mesh()
        try:
            if mesh is not None and LIGHTMAP_UV not in mesh.uv_layers:
                reports.warning("object '%s': its evaluated mesh lost the '%s' UV map (a modifier drops UV maps?)"
                                % (obj.name, LIGHTMAP_UV))
        finally:
            ev.to_mesh_clear()


# ---- engine warnings ---------------------------------------------------------------------------------------

def summarise_warnings(warnings, limit=3):
    """Engine warnings with those about individual meshes grouped: one line per mesh and kind of
    problem, and one summary line for a kind that more than `limit` meshes share."""
    groups, order, out = {}, [], []
    for w in warnings:
        m = re.match(r"^mesh '(.*?)': (.*)$", w)
        if m is None:
            out.append((len(order), w))
            order.append(None)
            continue
        name, rest = m.group(1), m.group(2)
        key = re.sub(r"\(first: [^)]*\)", "", re.sub(r"\d+", "#", rest))
        if key not in groups:
            groups[key] = []
            order.append(key)
        groups[key].append((name, rest))
    lines = []
    k = 0
    for key in order:
        if key is None:
            lines.append(out[k][1])
            k += 1
            continue
        items = groups[key]
        seen = []
        for name, rest in items:
            if (name, rest) not in seen:
                seen.append((name, rest))
        if len(seen) <= limit:
            lines += ["mesh '%s': %s" % (n, r) for n, r in seen]
            continue
        numbers = [int(x) for _, r in seen for x in re.findall(r"^\D*(\d+)", r)[:1]]
        names = ", ".join("'%s'" % n for n, _ in seen[:3])
        text = re.sub(r"\s*\(first: [^)]*\)", "", seen[0][1])
        if numbers:
            lo, hi = min(numbers), max(numbers)
            span = str(lo) if lo == hi else "%d-%d" % (lo, hi)
            text = re.sub(r"\d+", span, text, count=1)
        lines.append("%d meshes (%s and %d more), each: %s" % (len(seen), names, len(seen) - 3, text))
    return lines


def ensure_for_scene(context, objects, reports):
    """ensure_lightmap_uvs at the resolution the export will give each object (the scene's
    ResolutionRule) and with the scene's native subdivision setting."""
    density = ResolutionRule(context.scene.photonlm)
    return ensure_lightmap_uvs(context, objects, reports, density,
                               native_subdivision=getattr(context.scene.photonlm, "native_subdivision", True))
