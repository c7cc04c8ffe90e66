"""File > Export > PhotonLM scene (.json) (bake/scene_file.py writes it)."""
import bpy
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper

from ..bake import scene_file
from ..export.scene import Reports
from .bake import report_all


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
        reports = Reports()
        try:
            path, meta = scene_file.export_scene_file(context, self.filepath, reports)
        except (scene_file.ExportError, OSError, ValueError) as e:
            report_all(self, reports)
            self.report({'ERROR'}, "PhotonLM export: %s" % e)
            return {'CANCELLED'}
        except Exception as e:  # noqa: BLE001 -- never take Blender down
            report_all(self, reports)
            self.report({'ERROR'}, "PhotonLM export failed: %s" % e)
            return {'CANCELLED'}
        report_all(self, reports)
        self.report({'INFO'}, "Exported %d lightmaps to %s; bake with: %s"
                    % (len(meta["objects"]), path, scene_file.bake_command(path)))
        return {'FINISHED'}

def menu_export(self, context):
    self.layout.operator(PHOTONLM_OT_export_scene_file.bl_idname, text="PhotonLM scene (.json)")


def register():
    bpy.utils.register_class(PHOTONLM_OT_export_scene_file)
    bpy.types.TOPBAR_MT_file_export.append(menu_export)


def unregister():
    bpy.types.TOPBAR_MT_file_export.remove(menu_export)
    bpy.utils.unregister_class(PHOTONLM_OT_export_scene_file)
