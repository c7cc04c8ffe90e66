"""File > Export > PhotonLM scene (.json): the scene a bake would build, as a scene file
(docs/scene-file.md) for `photonlm bake SCENE.json -o DIR` on a batch machine.

The export runs the bake's own export (export.export_scene) against
photonlm.scene_file.SceneFileWriter, which has photonlm.Scene's methods and records the calls,
so the file holds exactly what a bake in Blender would trace: the same meshes (modifiers
applied, world space), materials, lights, world, CSG solids and OL groups, plus the scene's
bake settings. Automatic `lightmap` UV maps are made or refreshed first, as a bake does (they
are kept: the lightmaps baked from the file belong to them).

Where the lightmaps go: each object with a lightmap is a mesh named after the object, and
`photonlm bake` writes it to <object name>_lightmap.exr (unsafe characters as '_'). The file's
"metadata" lists, per object, the mesh index and that file name (and the OL groups'), for
scripts; File > Import > PhotonLM bake folder (bake_import.py) brings the baked folder back by
the mesh names report.json lists.
"""
import os
import types

import bpy
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper

from . import bake, bridge, export, uvmaps


class ExportError(Exception):
    """The export could not be written; the message is for the user."""


def export_scene_file(context, path, reports=None, obj_threshold=200_000):
    """Write the current view layer as a scene file at path. Returns (path, metadata dict).
    Meshes with more than obj_threshold triangles go to OBJ files in <stem>_meshes/ beside it.
    Raises ExportError (nothing to export, the bridge is missing) or OSError (cannot write)."""
    reports = reports if reports is not None else export.Reports()
    try:
        photonlm = bridge.get()
    except RuntimeError as e:
        raise ExportError(str(e)) from e
    from photonlm.scene_file import SceneFileWriter  # noqa: E402 -- the bridge is on sys.path now
    objects = export.lightmap_objects(context)
    uvmaps.commit(export.ensure_lightmap_uvs(context, objects, reports))
    writer = SceneFileWriter(obj_threshold=obj_threshold)
    factory = types.SimpleNamespace(Scene=lambda: writer)
    result = export.export_scene(context, factory, reports)
    if not result.baked and not writer.ol_groups:
        raise ExportError("nothing to export: no visible mesh object with 'Bake Lightmap' enabled "
                          "(or every one was skipped, see the reports)")
    for name, _ in result.lsystems:  # not reached today: the writer refuses L-systems
        reports.warning("L-system '%s' is not in the scene file" % name)
    writer.set_settings(**bake.bake_settings(context.scene))
    mesh_files, group_files = writer.output_files()
    writer.metadata = {
        "generator": "PhotonLM Blender add-on %s (photonlm %s)" % (
            ".".join(map(str, _addon_version())), photonlm.version()),
        "blend_file": bpy.data.filepath,
        "blender_scene": context.scene.name,
        "lightmap_uv": uvmaps.LIGHTMAP_UV,
        "objects": [{"object": b.object_name, "mesh": b.mesh_id,
                     "lightmap_file": mesh_files[writer.meshes[b.mesh_id]["name"]]} for b in result.baked],
        "ol_groups": [{"name": g.name, "group": g.group_id, "objects": list(g.objects),
                       "ol_file": group_files[writer.ol_groups[g.group_id].get("name", "ol%d" % g.group_id)]}
                      for g in result.ol_groups.values()],
    }
    # The CLI names files after the mesh and group names; the add-on after object names.
    try:
        path = writer.write(path)  # copies texture images next to the file
    finally:
        files = getattr(result, "texture_files", None)
        if files is not None and hasattr(files, "cleanup"):
            files.cleanup()
    reports.info("exported %d lightmapped objects, %d geometry-only objects, %d lights, %d OL groups, "
                 "%d CSG solids to %s" % (len(result.baked), result.geometry_only, result.lights,
                                          len(writer.ol_groups), len(writer.csg), path))
    return path, writer.metadata


def _addon_version():
    from . import VERSION
    return VERSION


class PHOTONLM_OT_export_scene_file(bpy.types.Operator, ExportHelper):
    """Export what a lightmap bake would trace as a PhotonLM scene file (JSON) for
    `photonlm bake SCENE.json -o DIR` on another machine"""
    bl_idname = "photonlm.export_scene_file"
    bl_label = "Export PhotonLM Scene"
    bl_options = {'REGISTER'}

    filename_ext = ".json"
    filter_glob: StringProperty(default="*.json", options={'HIDDEN'})

    @classmethod
    def poll(cls, context):
        if context.mode != 'OBJECT':
            cls.poll_message_set("Switch to Object Mode to export")
            return False
        return True

    def execute(self, context):
        reports = export.Reports()
        try:
            path, meta = export_scene_file(context, self.filepath, reports)
        except (ExportError, OSError, ValueError) as e:
            self._report_all(reports)
            self.report({'ERROR'}, "PhotonLM export: %s" % e)
            return {'CANCELLED'}
        except Exception as e:  # noqa: BLE001 -- never take Blender down
            self._report_all(reports)
            self.report({'ERROR'}, "PhotonLM export failed: %s" % e)
            return {'CANCELLED'}
        self._report_all(reports)
        self.report({'INFO'}, "Exported %d lightmaps to %s; bake with: photonlm bake \"%s\" -o DIR"
                    % (len(meta["objects"]), path, os.path.basename(path)))
        return {'FINISHED'}

    def _report_all(self, reports):
        for level, text in reports.items:
            self.report({level if level in ('INFO', 'WARNING', 'ERROR') else 'INFO'}, text)


def menu_export(self, context):
    self.layout.operator(PHOTONLM_OT_export_scene_file.bl_idname, text="PhotonLM scene (.json)")


def register():
    bpy.utils.register_class(PHOTONLM_OT_export_scene_file)
    bpy.types.TOPBAR_MT_file_export.append(menu_export)


def unregister():
    bpy.types.TOPBAR_MT_file_export.remove(menu_export)
    bpy.utils.unregister_class(PHOTONLM_OT_export_scene_file)
