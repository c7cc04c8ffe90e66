"""Blender scene -> photonlm.Scene: the whole export, through the converters of this package
(meshes.py reads every mesh, materials.py, lights.py, world.py, csg.py, subdiv.py, lsystem.py).
export_scene returns a SceneExport whose Manifest says what was sent: what the write-back
(writeback/apply.py) needs to bring the result back.

Runs on the main thread. Meshes come from the evaluated depsgraph (modifiers applied)
through foreach_get into numpy; nothing loops over vertices in Python.

What is exported
- Mesh objects that are visible (visible_get) and renderable (not hide_render): with
  object.photonlm.enabled they get a lightmap (UV map `lightmap`, resolution from
  object.photonlm.resolution or the scene's texel density); otherwise, and for instances
  (particles, collection instances) and curve/text/metaball objects, they are geometry
  only: they block and reflect light but get no lightmap.
- Lights: point, spot, sun, area (square/rectangle -> AREA_RECT, disk/ellipse -> AREA_DISK);
  Cycles portal lights (square/rectangle) -> PORTAL
  with colour, power, world matrix, soft size, sun angle, area size, spot size/blend. Colour and
  power are what Cycles emits (lights.py); a light whose node tree is more than the default
  Emission is reported (its nodes are not baked).
- World: Background colour x strength (a uniform radiance), or world.color without nodes.
- Light groups (lightgroups.py): the view layer's Light Groups that lights, emissive objects or
  the world name; each emitter goes to its group (Manifest.light_groups lists them).
"""
import dataclasses
import re

import numpy as np

from .. import compat, stages
from . import csg, lightgroups, lights, lsystem, materials, subdiv
from . import world as world_export
from .resolution import AUTO_TRIANGLES_PER_TEXEL, ResolutionRule
from .meshes import LIGHTMAP_UV, mesh_arrays, shading_normals, surface_area

GEOMETRY_TYPES = {'MESH', 'CURVE', 'SURFACE', 'META', 'FONT'}


class Reports:
    """Messages for the user, collected during a bake: (level, text) with level INFO/WARNING/ERROR."""

    def __init__(self):
        self.items = []

    def add(self, level, text):
        self.items.append((level, text))
        print("PhotonLM %s: %s" % (level.lower(), text))

    def info(self, text):
        self.add('INFO', text)

    def warning(self, text):
        self.add('WARNING', text)

    def error(self, text):
        self.add('ERROR', text)

    def texts(self, level=None):
        return [t for (l, t) in self.items if level is None or l == level]


class BakedObject:
    """One object that gets a lightmap."""

    def __init__(self, obj, mesh_id, width, height, material_names):
        self.object_name = obj.name
        self.mesh_id = mesh_id
        self.width = width
        self.height = height
        self.material_names = material_names  # names of the materials on its slots (may repeat)


def object_resolution(obj, area, density):
    """density: the scene's ResolutionRule; area: m^2, or a function giving it (called
    only where the size follows from the area: the area of a large mesh costs time)."""
    return density(obj, area)


def safe_file_name(name):
    """An object name as a portable file name (no path separators or reserved characters)."""
    s = re.sub(r'[^A-Za-z0-9._-]+', "_", name).strip("._")
    return s or "object"


def is_renderable(obj, view_layer):
    return obj.visible_get(view_layer=view_layer) and not obj.hide_render


def lightmap_objects(context, selected_only=False):
    """Original objects that get a lightmap (only the selected ones: selected_only), sorted by name."""
    vl = context.view_layer
    return sorted((o for o in vl.objects if o.type == 'MESH' and o.photonlm.enabled and is_renderable(o, vl)
                   and (not selected_only or o.select_get(view_layer=vl))), key=lambda o: o.name)


def bake_settings(scene):
    """The scene's PhotonLM settings as arguments of photonlm.Scene.bake (also written into
    exported scene files, so that `photonlm bake` bakes what the add-on would)."""
    settings = scene.photonlm
    texel_value = settings.texel_value  # 'CYCLES': what this Blender's Cycles bake holds
    if texel_value == 'CYCLES':
        texel_value = compat.cycles_texel_value()
    out = dict(photons=int(settings.photons), max_bounces=int(settings.max_bounces),
               seed=int(settings.seed), target_error=float(settings.target_error),
               time_budget=float(settings.time_budget), direct_samples=int(settings.direct_samples),
               texel_value=texel_value, dilation=int(settings.lightmap_margin))
    if settings.directional:  # only when on: a bake (and a scene file) without it is as before
        out["directional"] = True
    return out


def directional_conflict(manifest, directional):
    """Why a directional bake of what the export found would be refused (directional lightmaps are
    made for ordinary lightmaps only: not with light groups, orientation lightmaps, CSG solids or
    L-system objects), or "". The engine refuses the same; this says it before the bake starts,
    in the panel's words."""
    if not directional:
        return ""
    if manifest.light_groups:
        return ("Directional lightmaps cannot be baked with light groups (%s): turn Directional off, or "
                "clear the view layer's Light Groups" % ", ".join(manifest.light_groups))
    others = [("orientation lightmaps", [g.name for g in manifest.ol_groups.values()]),
              ("exact CSG shapes", list(manifest.csg_objects)),
              ("L-system objects", [name for name, _ in manifest.lsystems])]
    for what, names in others:
        if names:
            return ("Directional lightmaps are made for ordinary lightmaps only, and the scene has %s (%s): turn "
                    "Directional off, or bake those objects as plain lightmaps"
                    % (what, ", ".join("'%s'" % n for n in names[:5]) + (", ..." if len(names) > 5 else "")))
    return ""


class _Quiet:
    """A Reports stand-in that keeps nothing (for looking at the scene as the export would)."""

    def info(self, text):
        pass

    warning = error = add = info


class _LightRecorder:
    """A photonlm.Scene stand-in for lights.add_light: records what would emit."""

    def __init__(self):
        self.emitting = []

    def add_light(self, kind, name="", **settings):
        if kind != 'PORTAL':
            self.emitting.append("light '%s'" % name)


def light_sources(context, limit=1):
    """What would light the scene, as the export sees it: visible lights with power and a colour,
    visible objects with an emissive material, a world that is not black. Stops after `limit`
    finds (0 = all). A list of descriptions; empty when nothing lights the scene."""
    recorder, quiet = _LightRecorder(), _Quiet()
    if world_export.emits(context.scene.world):  # without rendering a sky
        recorder.emitting.append("the world")
    view_layer = context.view_layer
    emissive = {}
    depsgraph = context.evaluated_depsgraph_get()
    for inst in depsgraph.object_instances:
        if limit and len(recorder.emitting) >= limit:
            break
        obj = inst.object
        parent = inst.parent.original if inst.is_instance and inst.parent else obj.original
        if not is_renderable(parent, view_layer):
            continue
        if obj.type == 'LIGHT':
            lights.add_light(recorder, obj, inst.matrix_world, quiet)
        elif obj.type in GEOMETRY_TYPES:
            for slot in obj.material_slots:
                mat = slot.material
                if mat is None:
                    continue
                if mat.name_full not in emissive:
                    emissive[mat.name_full] = max(materials.read_material(mat).emission) > 0.0
                if emissive[mat.name_full]:
                    recorder.emitting.append("material '%s' on '%s'" % (mat.name, obj.original.name))
                    break
    return recorder.emitting


def unlit_scene_message(context):
    """Why nothing lights the scene, naming lights that do not count (hidden, no power, black)."""
    view_layer = context.view_layer
    idle = []
    for obj in context.scene.objects:
        if obj.type != 'LIGHT':
            continue
        light = obj.data
        if light.type == 'AREA' and getattr(getattr(light, "cycles", None), "is_portal", False):
            continue
        if not is_renderable(obj, view_layer):
            idle.append("'%s' is hidden" % obj.name)
        elif light.energy <= 0.0:
            idle.append("'%s' has no power" % obj.name)
        elif max(light.color) <= 0.0:
            idle.append("'%s' is black" % obj.name)
    text = ("nothing lights the scene: no visible light with power, no emissive material and a black world, "
            "so every lightmap would be black. Add a light, an emissive material or a world colour")
    if idle:
        text += " (light %s%s)" % (", ".join(idle[:3]), ", ..." if len(idle) > 3 else "")
    return text


@dataclasses.dataclass
class Manifest:
    """What an export sent to the engine, and what the write-back needs to bring the result back
    (writeback/apply.py); a bake folder's report gives the same (bake/folder.py)."""
    baked: list = dataclasses.field(default_factory=list)         # BakedObject: objects with a lightmap
    ol_groups: dict = dataclasses.field(default_factory=dict)     # key -> OlGroup
    lsystems: list = dataclasses.field(default_factory=list)      # (object name, engine id) of L-system objects
    csg_objects: list = dataclasses.field(default_factory=list)   # names of objects traced as exact CSG solids
    light_groups: list = dataclasses.field(default_factory=list)  # names of the declared light groups
    triangles: int = 0          # triangles the engine traces (refined ones for subdivision cages)
    selected_only: bool = False  # Bake Selected: the other objects' lightmaps and OLs stay as they are
    target_error: float = 0.0    # the bake's target error (0: none)


class SceneExport:
    """The bridge scene being built, its textures, and the manifest of what it holds."""

    def __init__(self, plm_scene, times=None):
        self.scene = plm_scene
        self.times = times if times is not None else stages.StageTimes()  # seconds per export stage
        self.manifest = Manifest()  # what the bake sends: objects, OLs, L-systems, CSG solids, triangles
        self.material_ids = {}      # material key -> engine id
        self.material_info = {}     # material key -> MaterialInfo
        self.geometry_only = 0
        self.lights = 0
        self.cages = 0              # objects added as subdivision cages (refined by the engine)
        self.texture_files = materials.TextureFiles()  # images for the engine; cleanup() after the bake
        self.groups = lightgroups.GroupIds([], [])     # the declared light groups (lightgroups.py)


class OlGroup:
    """One orientation lightmap of the export: an object's own, or a collection's."""

    def __init__(self, group_id, name, reason):
        self.group_id = group_id
        self.name = name
        self.reason = reason
        self.objects = []           # object names whose light it holds


def _material_key(mat):
    return mat.name_full if mat is not None else None


def export_scene(context, photonlm, reports, selected_only=False, times=None):
    """Build a photonlm.Scene from the current view layer. Must run on the main thread.

    selected_only: only the selected objects get lightmaps (and selected L-system objects their
    light); every other visible object is exported as geometry that blocks and reflects light.
    A mesh the engine rejects (NaN coordinates, bad indices...) is reported and skipped.
    times (a stages.StageTimes): where the seconds of each stage are added up.
    Returns a SceneExport (.manifest: what was sent); the caller closes .scene.
    """
    times = times if times is not None else stages.StageTimes()
    scene = context.scene
    view_layer = context.view_layer
    cages = {}  # objects whose last modifier is a Subdivision Surface go as their cage (subdiv.py)
    if getattr(scene.photonlm, "native_subdivision", True):
        with times("export_cages"):
            cages = subdiv.read_cages(context, subdiv.candidates(
                [o for o in view_layer.objects if is_renderable(o, view_layer)], reports), reports)
    with times("export_depsgraph"):
        depsgraph = context.evaluated_depsgraph_get()
    density = ResolutionRule(scene.photonlm)
    plm = photonlm.Scene()
    compat.set_cycles_conventions(plm)  # lights as this Blender's Cycles has them
    export = SceneExport(plm, times)
    export.manifest.selected_only = selected_only
    with times("export_world"):
        world = world_export.start(scene.world)  # a sky to render renders beside the mesh export
    try:
        export.groups = declare_light_groups(plm, context)
        export.manifest.light_groups = list(export.groups.names)
        default_id = _add_material(export, plm, None, reports)
        bake_names = {o.name for o in lightmap_objects(context, selected_only)}
        for inst in depsgraph.object_instances:
            obj_eval = inst.object
            orig = obj_eval.original
            parent = inst.parent.original if inst.is_instance and inst.parent else orig
            if not is_renderable(parent, view_layer):
                continue
            if obj_eval.type == 'LIGHT':
                if lights.add_light(plm, obj_eval, inst.matrix_world, reports, export.groups.of(orig)):
                    export.lights += 1
                continue
            if obj_eval.type not in GEOMETRY_TYPES:
                continue
            if not inst.is_instance and lsystem.is_lsystem(orig):
                _add_lsystem(export, plm, orig, inst.matrix_world.copy(), default_id, reports,
                             baked=not selected_only or orig.select_get(view_layer=view_layer))
                continue
            with_lightmap = (not inst.is_instance) and orig.name in bake_names
            cage = None if inst.is_instance else cages.get(orig.name)
            with times("export_meshes"):
                if cage is not None and _add_subdiv_object(export, plm, orig, obj_eval, cage, with_lightmap,
                                                           density, default_id, reports):
                    continue
                _add_object(export, plm, orig, obj_eval, inst.matrix_world.copy(), inst.is_instance,
                            with_lightmap, density, default_id, reports)
        if export.cages:
            with times("export_refine"):  # the engine refines every cage at once, on every core
                plm.refine_subdiv_meshes()
        with times("export_world"):
            sun_light = world_export.set_world(plm, scene.world, reports, world)
            if export.groups.of(scene.world):
                plm.set_light_group(export.groups.of(scene.world), world=True)
                if sun_light is not None:
                    plm.set_light_group(export.groups.of(scene.world), light=sun_light)
    except BaseException:
        world.cancel()
        plm.close()
        raise
    return export


def light_group_plan(context):
    """The light groups an export declares (export/lightgroups.py): the view layer's Light Groups
    that a visible light, emissive object or the world names, in its order; [] for none."""
    view_layer = context.view_layer
    declared = set(lightgroups.view_layer_groups(view_layer))
    if not declared:
        return []
    emitters = [context.scene.world] if world_export.emits(context.scene.world) else []
    for obj in view_layer.objects:
        if lightgroups.lightgroup_of(obj) not in declared or not is_renderable(obj, view_layer):
            continue
        if obj.type == 'LIGHT' or any(s.material is not None and max(materials.read_material(s.material).emission) > 0.0
                                      for s in obj.material_slots):
            emitters.append(obj)
    return lightgroups.plan(view_layer, emitters)


def declare_light_groups(plm, context):
    """Declare the planned light groups in the engine scene (checking their names first: ValueError
    naming the one it refuses). Returns the lightgroups.GroupIds."""
    names = light_group_plan(context)
    lightgroups.check_names(names)
    return lightgroups.GroupIds(names, [plm.add_light_group(n) for n in names])


def _set_mesh_group(export, plm, orig, mesh_id):
    """Put a mesh's emission into its object's light group (nothing without groups)."""
    group = export.groups.of(orig)
    if group:
        plm.set_light_group(group, mesh=mesh_id)


def _add_material(export, plm, mat, reports):
    key = _material_key(mat)
    if key in export.material_ids:
        return export.material_ids[key]
    with export.times("export_materials"):
        return _read_material(export, plm, mat, key, reports)


def _read_material(export, plm, mat, key, reports):
    info = materials.read_material(mat)
    for note in info.notes:
        reports.warning(note)
    mid = plm.add_material(info.albedo, info.emission, name=info.name)
    materials.export_textures(plm, mid, info, export.texture_files, reports)
    materials.export_lobes(plm, mid, info, reports)
    export.material_ids[key] = mid
    export.material_info[key] = info
    return mid


def _object_materials(obj_eval, mesh):
    slots = [s.material for s in obj_eval.material_slots]
    if not slots and mesh is not None:
        slots = list(mesh.materials)
    return slots


def _add_object(export, plm, orig, obj_eval, matrix, is_instance, with_lightmap, density, default_id,
                reports):
    name = orig.name if not is_instance else "%s (instance %d)" % (orig.name, export.geometry_only)
    try:
        mesh = obj_eval.to_mesh()
    except RuntimeError as e:
        reports.warning("object '%s': no mesh (%s): skipped" % (orig.name, e))
        return
    try:
        if mesh is None:
            return
        mesh.calc_loop_triangles()
        if len(mesh.loop_triangles) == 0:
            return
        pos, tris, mat_index, uv = mesh_arrays(mesh, matrix, with_lightmap)
        normals = shading_normals(mesh, matrix)
        mats = _object_materials(obj_eval, mesh)
        slot_ids = np.array([_add_material(export, plm, m, reports) if m is not None else default_id
                             for m in mats] or [default_id], dtype=np.uint32)
        mat_ids = slot_ids[np.clip(mat_index, 0, len(slot_ids) - 1)]
        tex_uv = materials.texture_uv(mesh, [export.material_info.get(_material_key(m)) for m in mats],
                                      orig.name, reports)
    finally:
        obj_eval.to_mesh_clear()
    if with_lightmap and uv is None:
        reports.warning("object '%s': its evaluated mesh has no '%s' UV map (a modifier removed it?): "
                        "baked as geometry only" % (orig.name, LIGHTMAP_UV))
        with_lightmap = False
    resolution = 0
    if with_lightmap:
        resolution = object_resolution(orig, lambda: surface_area(pos, tris), density)
    try:
        mesh_id = plm.add_mesh(name, pos, tris, lightmap_uv=uv if with_lightmap else None,
                               material_ids=mat_ids, resolution=resolution)
    except Exception as e:  # the engine names the mesh and the first bad index
        reports.warning("object '%s' skipped: %s" % (orig.name, getattr(e, "message", e)))
        return
    export.manifest.triangles += len(tris)
    _set_mesh_group(export, plm, orig, mesh_id)
    if tex_uv is not None and hasattr(plm, "set_mesh_texture_uv"):
        plm.set_mesh_texture_uv(mesh_id, tex_uv)
    if normals is not None:
        plm.set_mesh_normals(mesh_id, normals)
    group = _ol_group(export, plm, orig, len(tris), resolution if with_lightmap else 0, reports)
    if group is not None:
        plm.set_mesh_ol_group(mesh_id, group.group_id)
        if orig.name not in group.objects:
            group.objects.append(orig.name)
    elif with_lightmap and not is_instance and csg.is_csg_object(orig):
        _add_csg(export, plm, orig, mesh_id, default_id, reports)
    if with_lightmap:
        export.manifest.baked.append(BakedObject(orig, mesh_id, resolution, resolution,
                                        [(m.name if m is not None else None) for m in mats]))
    else:
        export.geometry_only += 1


def _add_subdiv_object(export, plm, orig, obj_eval, cage, with_lightmap, density, default_id, reports):
    """Add orig as its subdivision cage (refined by the engine); False to fall back to the mesh."""
    mats = _object_materials(obj_eval, None) or list(orig.data.materials)
    slot_ids = np.array([_add_material(export, plm, m, reports) if m is not None else default_id
                         for m in mats] or [default_id], dtype=np.uint32)
    infos = [export.material_info.get(_material_key(m)) for m in mats]
    if any(getattr(i, "albedo_texture", None) is not None or getattr(i, "emission_texture", None) is not None
           for i in infos):
        reports.info("object '%s': exported as Blender's subdivided mesh: a material has an image texture "
                     "(texture UVs are read from Blender's mesh only)" % orig.name)
        return False
    if with_lightmap and cage.uv is None:
        reports.warning("object '%s': its subdivision cage has no '%s' UV map: baked as geometry only"
                        % (orig.name, LIGHTMAP_UV))
        with_lightmap = False
    resolution = object_resolution(orig, cage.area, density) if with_lightmap else 0
    try:
        mesh_id = subdiv.add_cage(plm, orig.name, cage, with_lightmap, slot_ids, resolution)
    except Exception as e:  # the engine names the mesh and the first bad index
        reports.warning("object '%s': exported as Blender's subdivided mesh: the engine refused its cage: %s"
                        % (orig.name, getattr(e, "message", e)))
        return False
    reports.info("object '%s': subdivision level %d refined by the engine from a cage of %d faces"
                 % (orig.name, cage.level, len(cage.face_sizes)))
    export.cages += 1
    export.manifest.triangles += cage.triangle_count()
    _set_mesh_group(export, plm, orig, mesh_id)
    group = _ol_group(export, plm, orig, cage.triangle_count(), resolution, reports)
    if group is not None:
        plm.set_mesh_ol_group(mesh_id, group.group_id)
        if orig.name not in group.objects:
            group.objects.append(orig.name)
    if with_lightmap:
        export.manifest.baked.append(BakedObject(orig, mesh_id, resolution, resolution,
                                        [(m.name if m is not None else None) for m in mats]))
    else:
        export.geometry_only += 1
    return True


def _add_lsystem(export, plm, orig, matrix, default_id, reports, baked=True):
    """Add an L-system object from its rules (its mesh is only a preview), or report why not;
    baked: its light is brought back after the bake (else it only blocks and reflects)."""
    ids = [_add_material(export, plm, s.material, reports) if s.material is not None else default_id
           for s in orig.material_slots] or [default_id]
    try:
        lid = lsystem.export_lsystem(plm, orig, matrix, np.array(ids, np.uint32))
    except Exception as e:  # the engine names the line and column, or the limit
        reports.warning("L-system '%s' skipped: %s" % (orig.name, getattr(e, "message", e)))
        return
    if not baked:
        return
    export.manifest.lsystems.append((orig.name, lid))
    reports.info("L-system '%s': traced from its rules, lit through orientation lightmaps" % orig.name)


def _add_csg(export, plm, orig, mesh_id, default_id, reports):
    """Trace orig exactly as a CSG solid whose carrier is its baked mesh, or report why not."""
    def material_of(obj):
        mat = obj.material_slots[0].material if obj.material_slots else None
        return _add_material(export, plm, mat, reports) if mat is not None else default_id
    try:
        csg_id, count = csg.export_csg(plm, orig, material_of)
        plm.set_csg_carrier(csg_id, mesh_id)
    except csg.NotExact as e:
        reports.info("object '%s': baked as its mesh, not as an exact CSG solid: %s" % (orig.name, e))
        return
    except Exception as e:  # the engine names the bad primitive or node
        reports.warning("object '%s': baked as its mesh, the engine refused its CSG solid: %s"
                        % (orig.name, getattr(e, "message", e)))
        return
    export.manifest.csg_objects.append(orig.name)
    reports.info("object '%s': traced as an exact CSG solid of %d primitives" % (orig.name, count))


def _ol_group(export, plm, orig, triangles, resolution, reports):
    """The OL group an object's light goes to, or None for an ordinary lightmap: the first of its
    collections marked 'One Orientation Lightmap' (instances and objects without lightmaps too);
    else its own OL for mode ORIENTATION, or AUTO with more than AUTO_TRIANGLES_PER_TEXEL
    triangles per texel of its lightmap (not with light groups, which split ordinary lightmaps only).
    Only objects with a lightmap get their own OL."""
    for coll in orig.users_collection:
        settings = getattr(coll, "photonlm", None)
        if settings is not None and settings.orientation_lightmap:
            key = ("collection", coll.name_full)
            if key not in export.manifest.ol_groups:
                gid = plm.add_ol_group("collection " + coll.name, int(settings.ol_resolution))
                export.manifest.ol_groups[key] = OlGroup(gid, "collection_" + coll.name,
                                                "collection '%s' is set to one orientation lightmap" % coll.name)
            return export.manifest.ol_groups[key]
    if resolution == 0:
        return None
    mode = orig.photonlm.mode
    texels = resolution * resolution
    if mode == 'ORIENTATION':
        reason = "its Lighting is set to Orientation Lightmap"
    elif mode == 'BACKUP':
        reason = "its Lighting is set to Lightmap + OL Backup"
    elif mode == 'AUTO' and triangles > AUTO_TRIANGLES_PER_TEXEL * texels:
        if export.groups:  # light groups split ordinary lightmaps only
            reports.info("object '%s': a plain lightmap, not the orientation lightmap Auto would choose "
                         "(%d triangles on %d texels): the scene has light groups" % (orig.name, triangles, texels))
            return None
        reason = ("Auto: %d triangles on %d lightmap texels (more than %d per texel)"
                  % (triangles, texels, AUTO_TRIANGLES_PER_TEXEL))
    else:
        return None
    key = ("object", orig.name_full)
    if key not in export.manifest.ol_groups:
        gid = plm.add_ol_group(orig.name, int(orig.photonlm.ol_resolution))
        if mode == 'BACKUP':
            plm.set_ol_group_backup(gid, True)
        export.manifest.ol_groups[key] = OlGroup(gid, orig.name, reason)
        reports.info("object '%s': orientation lightmap (%s)" % (orig.name, reason))
    return export.manifest.ol_groups[key]
