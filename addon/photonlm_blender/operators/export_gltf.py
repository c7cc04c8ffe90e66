"""File > Export > glTF with PhotonLM lightmaps (.glb) (gltf/export.py writes it)."""
import bpy
from bpy.props import BoolProperty, StringProperty
from bpy_extras.io_utils import ExportHelper

from ..gltf import export


class PHOTONLM_OT_export_gltf(bpy.types.Operator, ExportHelper):
    """Export the scene as a binary glTF (.glb) with Blender's glTF exporter, each baked object's
    material carrying its lightmap (RGBM PNG on TEXCOORD_1, as MOZ_lightmap and FB_materials_lightmap)"""
    bl_idname = "photonlm.export_gltf"
    bl_label = "Export glTF with Lightmaps"
    bl_options = {'REGISTER'}

    filename_ext = ".glb"
    filter_glob: StringProperty(default="*.glb", options={'HIDDEN'})
    use_selection: BoolProperty(name="Selected Objects", default=False,
                                description="Export the selected objects only (else every visible object)")

    @classmethod
    def poll(cls, context):
        if context.mode != 'OBJECT':
            cls.poll_message_set("Switch to Object Mode to export")
            return False
        return True

    def execute(self, context):
        try:
            summary = export.export_glb(context, self.filepath, self.use_selection)
        except export.ExportError as e:
            self.report({'ERROR'}, "PhotonLM glTF export: %s" % e)
            return {'CANCELLED'}
        except Exception as e:  # noqa: BLE001 -- never take Blender down
            self.report({'ERROR'}, "PhotonLM glTF export failed: %s" % e)
            return {'CANCELLED'}
        for note in summary["notes"]:
            self.report({'WARNING'}, note)
        size = summary["size"]
        self.report({'INFO'}, "Exported %d objects with lightmaps (%d textures) to %s (%s, %.2f s)"
                    % (len(summary["objects"]), len(summary["textures"]), summary["path"],
                       "%.1f MB" % (size / 1e6) if size >= 1e6 else "%.0f KB" % (size / 1e3), summary["seconds"]))
        return {'FINISHED'}


def menu_export(self, context):
    self.layout.operator(PHOTONLM_OT_export_gltf.bl_idname, text="glTF with PhotonLM lightmaps (.glb)")


def register():
    bpy.utils.register_class(PHOTONLM_OT_export_gltf)
    bpy.types.TOPBAR_MT_file_export.append(menu_export)


def unregister():
    bpy.types.TOPBAR_MT_file_export.remove(menu_export)
    bpy.utils.unregister_class(PHOTONLM_OT_export_gltf)
