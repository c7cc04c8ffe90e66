"""File > Import > PhotonLM bake folder (bake/folder.py reads it, writeback/apply.py brings it in)."""
import os

import bpy
from bpy.props import BoolProperty, StringProperty

from ..bake import folder as bake_folder
from .bake import report_all, running


class PHOTONLM_OT_import_bake_folder(bpy.types.Operator):
    """Bring in the lightmaps of a bake folder (report.json and EXRs from photonlm bake or photonlm merge
    of this scene's exported scene file) as a bake in Blender does: images, material wiring, statistics"""
    bl_idname = "photonlm.import_bake_folder"
    bl_label = "Import PhotonLM Bake Folder"
    bl_options = {'REGISTER', 'UNDO'}

    directory: StringProperty(name="Folder", subtype='DIR_PATH',
                              description="Folder holding report.json and the lightmap EXRs")
    filepath: StringProperty(subtype='FILE_PATH', options={'HIDDEN', 'SKIP_SAVE'})
    filter_folder: BoolProperty(default=True, options={'HIDDEN'})
    filter_glob: StringProperty(default="*.json", options={'HIDDEN'})

    @classmethod
    def poll(cls, context):
        if running() is not None:
            cls.poll_message_set("A lightmap bake is running")
            return False
        if context.mode != 'OBJECT':
            cls.poll_message_set("Switch to Object Mode to import lightmaps")
            return False
        return True

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {'RUNNING_MODAL'}

    def execute(self, context):
        folder = self.directory or (os.path.dirname(self.filepath) if self.filepath else "")
        if not folder:
            self.report({'ERROR'}, "PhotonLM import: no folder given")
            return {'CANCELLED'}
        reports = None
        try:
            job = bake_folder.BakeFolder(context, folder)
            reports = job.reports
            try:
                last = job.finish(context)
            except BaseException:
                job.abort(context)
                raise
        except (bake_folder.FolderError, RuntimeError) as e:
            report_all(self, reports)
            self.report({'ERROR'}, "PhotonLM import: %s" % e)
            return {'CANCELLED'}
        except Exception as e:  # noqa: BLE001 -- never take Blender down
            report_all(self, reports)
            self.report({'ERROR'}, "PhotonLM import of '%s' failed: %s" % (folder, getattr(e, "message", None) or e))
            return {'CANCELLED'}
        report_all(self, reports)
        s = last["stats"]
        self.report({'INFO'}, "Imported %d lightmaps%s from %s: %s photons, error %.2f %%, %d warnings"
                    % (len(last["objects"]), " and %d OLs" % len(last["ols"]) if last["ols"] else "", job.folder,
                       "{:,}".format(int(s["photons_emitted"])), 100.0 * s["error_estimate"], s["warning_count"]))
        for text in job.notices:
            self.report({'WARNING'}, text)
        return {'FINISHED'}

def menu_import(self, context):
    self.layout.operator(PHOTONLM_OT_import_bake_folder.bl_idname, text="PhotonLM bake folder")


def register():
    bpy.utils.register_class(PHOTONLM_OT_import_bake_folder)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    bpy.utils.unregister_class(PHOTONLM_OT_import_bake_folder)
