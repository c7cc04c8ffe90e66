"""File > Import > glTF with PhotonLM lightmaps (.glb) (gltf/rewire.py imports and wires it)."""
import bpy
from bpy.props import StringProperty
from bpy_extras.io_utils import ImportHelper

from ..gltf import export, rewire


class PHOTONLM_OT_import_gltf(bpy.types.Operator, ImportHelper):
    """Import a binary glTF (.glb) written with PhotonLM lightmaps: Blender's glTF importer makes the
    objects, and each material gets its lightmap back in the lightmap preview"""
    bl_idname = "photonlm.import_gltf"
    bl_label = "Import glTF with Lightmaps"
    bl_options = {'REGISTER', 'UNDO'}

    filename_ext = ".glb"
    filter_glob: StringProperty(default="*.glb", options={'HIDDEN'})

    @classmethod
    def poll(cls, context):
        if context.mode != 'OBJECT':
            cls.poll_message_set("Switch to Object Mode to import")
            return False
        return True

    def execute(self, context):
        try:
            summary = rewire.import_glb(context, self.filepath)
        except export.ExportError as e:
            self.report({'ERROR'}, "PhotonLM glTF import: %s" % e)
            return {'CANCELLED'}
        except Exception as e:  # noqa: BLE001 -- never take Blender down
            self.report({'ERROR'}, "PhotonLM glTF import failed: %s" % e)
            return {'CANCELLED'}
        for note in summary["notes"]:
            self.report({'WARNING'}, note)
        self.report({'INFO'}, "Imported %d objects with lightmaps from %s (%.2f s)"
                    % (len(summary["objects"]), summary["path"], summary["seconds"]))
        return {'FINISHED'}


def menu_import(self, context):
    self.layout.operator(PHOTONLM_OT_import_gltf.bl_idname, text="glTF with PhotonLM lightmaps (.glb)")


def register():
    bpy.utils.register_class(PHOTONLM_OT_import_gltf)
    bpy.types.TOPBAR_MT_file_import.append(menu_import)


def unregister():
    bpy.types.TOPBAR_MT_file_import.remove(menu_import)
    bpy.utils.unregister_class(PHOTONLM_OT_import_gltf)
