"""Blender scene -> photonlm.Scene.

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
  power are what Cycles emits (compat.light_emission: temperature, exposure, normalize); a light
  whose node tree is more than the default Emission is reported (its nodes are not baked).
- World: Background colour x strength (a uniform radiance), or world.color without nodes.
"""
import contextlib
import re

import numpy as np

from . import compat, csg_export, lsystem, materials, properties, stages, subdiv_export, uvmaps, world_export

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


def mesh_arrays(mesh, matrix_world, want_uv):
    """World-space positions (V,3) f32, triangles (T,3) u32, material indices (T,) i32 and the
    lightmap UV per triangle corner (T,3,2) f32 (None if not wanted or missing)."""
    nv, nt = len(mesh.vertices), len(mesh.loop_triangles)
    co = np.empty(nv * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    m = np.array(matrix_world, dtype=np.float64)
    pos = (co.reshape(nv, 3).astype(np.float64) @ m[:3, :3].T + m[:3, 3]).astype(np.float32)
    tris = np.empty(nt * 3, np.int32)
    mesh.loop_triangles.foreach_get("vertices", tris)
    mat_index = np.empty(nt, np.int32)
    mesh.loop_triangles.foreach_get("material_index", mat_index)
    uv = None
    layer = mesh.uv_layers.get(uvmaps.LIGHTMAP_UV)
    if want_uv and layer is not None:
        loops = np.empty(nt * 3, np.int32)
        mesh.loop_triangles.foreach_get("loops", loops)
        loop_uv = np.empty(len(mesh.loops) * 2, np.float32)
        layer.data.foreach_get("uv", loop_uv)
        uv = loop_uv.reshape(-1, 2)[loops].reshape(nt, 3, 2)
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
    poly = np.empty(nt, np.int32)
    mesh.loop_triangles.foreach_get("polygon_index", poly)
    # Normals transform with the inverse transpose of the object's linear part.
    m = np.array(matrix_world, dtype=np.float64)[:3, :3]
    try:
        normal_matrix = np.linalg.inv(m).T
    except np.linalg.LinAlgError:
        return None  # a flattened object: no direction to shade with
    n = n @ normal_matrix.T
    n[~smooth[poly]] = 0.0
    return n.astype(np.float32)


def surface_area(pos, tris):
    if len(tris) == 0:
        return 0.0
    p = pos.astype(np.float64)
    a, b, c = p[tris[:, 0]], p[tris[:, 1]], p[tris[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    return float(np.nansum(area[np.isfinite(area)]))


def object_resolution(obj, area, density):
    """density: the scene's properties.ResolutionRule; area: m^2, or a function giving it (called
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


def ensure_lightmap_uvs(context, objects, reports):
    """Make or refresh the automatic `lightmap` UV maps of the objects that have no map of the user's
    (uvmaps.py): made for the evaluated mesh, at the resolution the export will give each object.
    Returns a uvmaps.Changes list (undo() for a cancelled or failed bake, commit() to keep them)."""
    density = properties.ResolutionRule(context.scene.photonlm)
    return uvmaps.ensure_lightmap_uvs(
        context, objects, reports, lambda obj, area: object_resolution(obj, area, density),
        native_subdivision=getattr(context.scene.photonlm, "native_subdivision", True))


class SceneExport:
    """The bridge scene plus what the bake needs to bring results back."""

    def __init__(self, plm_scene, times=None):
        self.scene = plm_scene
        self.times = times if times is not None else stages.StageTimes()  # seconds per export stage
        self.triangles = 0          # triangles the engine traces (refined ones for subdivision cages)
        self.baked = []             # BakedObject
        self.material_ids = {}      # material key -> engine id
        self.material_info = {}     # material key -> MaterialInfo
        self.geometry_only = 0
        self.lights = 0
        self.ol_groups = {}         # key -> OlGroup
        self.cages = 0              # objects added as subdivision cages (refined by the engine)
        self.csg_objects = []       # names of objects traced as exact CSG solids
        self.lsystems = []          # (object name, engine id) of L-system objects
        self.texture_files = materials.TextureFiles()  # images for the engine; cleanup() after the bake


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
    Returns a SceneExport; the caller closes .scene.
    """
    times = times if times is not None else stages.StageTimes()
    scene = context.scene
    view_layer = context.view_layer
    cages = {}  # objects whose last modifier is a Subdivision Surface go as their cage (subdiv_export.py)
    if getattr(scene.photonlm, "native_subdivision", True):
        with times("export_cages"):
            cages = subdiv_export.read_cages(context, subdiv_export.candidates(
                [o for o in view_layer.objects if is_renderable(o, view_layer)], reports), reports)
    with times("export_depsgraph"):
        depsgraph = context.evaluated_depsgraph_get()
    density = properties.ResolutionRule(scene.photonlm)
    plm = photonlm.Scene()
    compat.set_cycles_conventions(plm)  # lights as this Blender's Cycles has them
    export = SceneExport(plm, times)
    with times("export_world"):
        world = world_export.start(scene.world)  # a sky to render renders beside the mesh export
    try:
        default_id = _add_material(export, plm, None, reports)
        bake_names = {o.name for o in lightmap_objects(context, selected_only)}
        for inst in depsgraph.object_instances:
            obj_eval = inst.object
            orig = obj_eval.original
            parent = inst.parent.original if inst.is_instance and inst.parent else orig
            if not is_renderable(parent, view_layer):
                continue
            if obj_eval.type == 'LIGHT':
                if _add_light(plm, obj_eval, inst.matrix_world, reports):
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
            world_export.set_world(plm, scene.world, reports, world)
    except BaseException:
        world.cancel()
        plm.close()
        raise
    return export


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
                        "baked as geometry only" % (orig.name, uvmaps.LIGHTMAP_UV))
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
    export.triangles += len(tris)
    if tex_uv is not None and hasattr(plm, "set_mesh_texture_uv"):
        plm.set_mesh_texture_uv(mesh_id, tex_uv)
    if normals is not None:
        plm.set_mesh_normals(mesh_id, normals)
    group = _ol_group(export, plm, orig, len(tris), resolution if with_lightmap else 0, reports)
    if group is not None:
        plm.set_mesh_ol_group(mesh_id, group.group_id)
        if orig.name not in group.objects:
            group.objects.append(orig.name)
    elif with_lightmap and not is_instance and csg_export.is_csg_object(orig):
        _add_csg(export, plm, orig, mesh_id, default_id, reports)
    if with_lightmap:
        export.baked.append(BakedObject(orig, mesh_id, resolution, resolution,
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
                        % (orig.name, uvmaps.LIGHTMAP_UV))
        with_lightmap = False
    resolution = object_resolution(orig, cage.area, density) if with_lightmap else 0
    try:
        mesh_id = subdiv_export.add_cage(plm, orig.name, cage, with_lightmap, slot_ids, resolution)
    except Exception as e:  # the engine names the mesh and the first bad index
        reports.warning("object '%s': exported as Blender's subdivided mesh: the engine refused its cage: %s"
                        % (orig.name, getattr(e, "message", e)))
        return False
    reports.info("object '%s': subdivision level %d refined by the engine from a cage of %d faces"
                 % (orig.name, cage.level, len(cage.face_sizes)))
    export.cages += 1
    export.triangles += cage.triangle_count()
    group = _ol_group(export, plm, orig, cage.triangle_count(), resolution, reports)
    if group is not None:
        plm.set_mesh_ol_group(mesh_id, group.group_id)
        if orig.name not in group.objects:
            group.objects.append(orig.name)
    if with_lightmap:
        export.baked.append(BakedObject(orig, mesh_id, resolution, resolution,
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
    export.lsystems.append((orig.name, lid))
    reports.info("L-system '%s': traced from its rules, lit through orientation lightmaps" % orig.name)


def _add_csg(export, plm, orig, mesh_id, default_id, reports):
    """Trace orig exactly as a CSG solid whose carrier is its baked mesh, or report why not."""
    def material_of(obj):
        mat = obj.material_slots[0].material if obj.material_slots else None
        return _add_material(export, plm, mat, reports) if mat is not None else default_id
    try:
        csg_id, count = csg_export.export_csg(plm, orig, material_of)
        plm.set_csg_carrier(csg_id, mesh_id)
    except csg_export.NotExact as e:
        reports.info("object '%s': baked as its mesh, not as an exact CSG solid: %s" % (orig.name, e))
        return
    except Exception as e:  # the engine names the bad primitive or node
        reports.warning("object '%s': baked as its mesh, the engine refused its CSG solid: %s"
                        % (orig.name, getattr(e, "message", e)))
        return
    export.csg_objects.append(orig.name)
    reports.info("object '%s': traced as an exact CSG solid of %d primitives" % (orig.name, count))


def _ol_group(export, plm, orig, triangles, resolution, reports):
    """The OL group an object's light goes to, or None for an ordinary lightmap: the first of its
    collections marked 'One Orientation Lightmap' (instances and objects without lightmaps too);
    else its own OL for mode ORIENTATION, or AUTO with more than AUTO_TRIANGLES_PER_TEXEL
    triangles per texel of its lightmap. Only objects with a lightmap get their own OL."""
    for coll in orig.users_collection:
        settings = getattr(coll, "photonlm", None)
        if settings is not None and settings.orientation_lightmap:
            key = ("collection", coll.name_full)
            if key not in export.ol_groups:
                gid = plm.add_ol_group("collection " + coll.name, int(settings.ol_resolution))
                export.ol_groups[key] = OlGroup(gid, "collection_" + coll.name,
                                                "collection '%s' is set to one orientation lightmap" % coll.name)
            return export.ol_groups[key]
    if resolution == 0:
        return None
    mode = orig.photonlm.mode
    texels = resolution * resolution
    if mode == 'ORIENTATION':
        reason = "its Lighting is set to Orientation Lightmap"
    elif mode == 'BACKUP':
        reason = "its Lighting is set to Lightmap + OL Backup"
    elif mode == 'AUTO' and triangles > properties.AUTO_TRIANGLES_PER_TEXEL * texels:
        reason = ("Auto: %d triangles on %d lightmap texels (more than %d per texel)"
                  % (triangles, texels, properties.AUTO_TRIANGLES_PER_TEXEL))
    else:
        return None
    key = ("object", orig.name_full)
    if key not in export.ol_groups:
        gid = plm.add_ol_group(orig.name, int(orig.photonlm.ol_resolution))
        if mode == 'BACKUP':
            plm.set_ol_group_backup(gid, True)
        export.ol_groups[key] = OlGroup(gid, orig.name, reason)
        reports.info("object '%s': orientation lightmap (%s)" % (orig.name, reason))
    return export.ol_groups[key]


def _add_light(plm, obj_eval, matrix, reports):
    light = obj_eval.data
    m = [list(row) for row in matrix]
    if light.type == 'AREA' and getattr(getattr(light, "cycles", None), "is_portal", False):
        if light.shape not in ('SQUARE', 'RECTANGLE'):
            reports.warning("portal '%s': only square and rectangle portals are supported: skipped" % obj_eval.name)
            return False
        sy = light.size_y if light.shape == 'RECTANGLE' else light.size
        try:
            plm.add_light('PORTAL', name=obj_eval.name, matrix=m, size=light.size, size_y=sy)
        except Exception as e:
            reports.warning("portal '%s' skipped: %s" % (obj_eval.name, getattr(e, "message", e)))
            return False
        reports.info("portal '%s': sun and sky light are sampled through it" % obj_eval.name)
        return True
    color, power = compat.light_emission(light, lambda: _area_light_area(light, matrix))
    if power <= 0.0 or max(color) <= 0.0:
        return False
    if compat.light_nodes_differ(light):
        reports.warning("light '%s': light nodes are ignored (colour and power come from the light's "
                        "settings)" % obj_eval.name)
    kw = dict(name=obj_eval.name, color=color, power=power, matrix=m)
    t = light.type
    try:
        if t == 'POINT':
            plm.add_light('POINT', radius=light.shadow_soft_size, **kw)
        elif t == 'SPOT':
            plm.add_light('SPOT', radius=light.shadow_soft_size, spot_size=light.spot_size,
                          spot_blend=light.spot_blend, **kw)
        elif t == 'SUN':
            plm.add_light('SUN', angle=light.angle, **kw)
        elif t == 'AREA':
            shape = light.shape
            sy = light.size_y if shape in ('RECTANGLE', 'ELLIPSE') else light.size
            plm.add_light('AREA_RECT' if shape in ('SQUARE', 'RECTANGLE') else 'AREA_DISK',
                          size=light.size, size_y=sy, **kw)
        else:
            reports.warning("light '%s': type %s is not supported: skipped" % (obj_eval.name, t))
            return False
    except Exception as e:
        reports.warning("light '%s' skipped: %s" % (obj_eval.name, getattr(e, "message", e)))
        return False
    return True


def _area_light_area(light, matrix):
    """World-space area of an area light as Cycles measures it: its size along the object's scaled
    X and Y axes, x pi/4 for disks and ellipses."""
    m = np.array(matrix, dtype=np.float64)
    sy = light.size_y if light.shape in ('RECTANGLE', 'ELLIPSE') else light.size
    area = float(light.size) * np.linalg.norm(m[:3, 0]) * float(sy) * np.linalg.norm(m[:3, 1])
    return area * (np.pi / 4.0 if light.shape in ('DISK', 'ELLIPSE') else 1.0)
