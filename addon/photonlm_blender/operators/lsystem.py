"""L-system operators: add an L-system object from a preset, rebuild the preview mesh from its rules."""
import bpy
from bpy.props import EnumProperty

from ..export.lsystem import PRESETS, update_preview


class PHOTONLM_OT_add_lsystem(bpy.types.Operator):
    """Add an L-system object from a preset (baked from its rules; the mesh is a capped preview)"""
    bl_idname = "photonlm.add_lsystem"
    bl_label = "Add L-System"
    bl_options = {'REGISTER', 'UNDO'}

    preset: EnumProperty(name="Preset", items=[('SIERPINSKI', "Sierpinski", "Sierpinski triangle"),
                                               ('SYMPODIAL_TREE', "Sympodial Tree", "A sympodial tree"),
                                               ('BUSH', "Bush", "A bush with round leaves")],
                         default='SYMPODIAL_TREE')

    def execute(self, context):
        rules, settings = PRESETS[self.preset]
        mesh = bpy.data.meshes.new(self.preset.lower())
        obj = bpy.data.objects.new(self.preset.replace("_", " ").title(), mesh)
        context.collection.objects.link(obj)
        obj.location = context.scene.cursor.location
        ls = obj.photonlm.lsystem
        ls.enabled = True
        ls.rules = rules
        ls.depth = settings["depth"]
        ls.step = settings["step"]
        ls.width = settings["width"]
        obj.photonlm.enabled = False  # no lightmap: lit through its orientation lightmaps
        try:
            count = update_preview(obj)
        except Exception as e:  # noqa: BLE001 -- the engine names the line and column
            self.report({'ERROR'}, str(getattr(e, "message", None) or e))
            return {'CANCELLED'}
        for o in context.view_layer.objects:
            o.select_set(False)
        obj.select_set(True)
        context.view_layer.objects.active = obj
        self.report({'INFO'}, "Added L-system '%s' (%d preview triangles)" % (obj.name, count))
        return {'FINISHED'}


class PHOTONLM_OT_update_lsystem(bpy.types.Operator):
    """Rebuild the active L-system object's preview mesh from its rules"""
    bl_idname = "photonlm.update_lsystem"
    bl_label = "Update L-System Preview"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == 'MESH' and obj.photonlm.lsystem.enabled

    def execute(self, context):
        notes = []
        try:
            count = update_preview(context.active_object, notes)
        except Exception as e:  # noqa: BLE001 -- the engine names the object, line and column
            self.report({'ERROR'}, str(getattr(e, "message", None) or e))
            return {'CANCELLED'}
        for n in notes:
            self.report({'WARNING'}, n)
        self.report({'INFO'}, "L-system preview: %d triangles" % count)
        return {'FINISHED'}


_CLASSES = (PHOTONLM_OT_add_lsystem, PHOTONLM_OT_update_lsystem)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
