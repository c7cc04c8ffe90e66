"""Render Properties > PhotonLM Lightmaps."""
import bpy

from . import bridge, operators, uvmaps


class PHOTONLM_PT_lightmaps(bpy.types.Panel):
    bl_label = "PhotonLM Lightmaps"
    bl_idname = "PHOTONLM_PT_lightmaps"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.photonlm

        col = layout.column()
        col.prop(settings, "target_error")
        col.prop(settings, "time_budget")
        col.prop(settings, "photons")
        col.prop(settings, "direct_samples")
        col.prop(settings, "texel_value")
        col.prop(settings, "max_bounces")
        col.prop(settings, "texel_density")
        col.prop(settings, "native_subdivision")
        col.prop(settings, "seed")
        col.prop(settings, "output_dir")

        row = layout.row()
        row.scale_y = 1.5
        running = operators._running is not None
        row.operator("photonlm.bake", icon='RENDER_STILL',
                     text="Baking... (Esc to cancel)" if running else "Bake Lightmaps")
        if bridge.error():
            layout.label(text=bridge.error(), icon='ERROR')
        layout.operator_menu_enum("photonlm.add_lsystem", "preset", text="Add L-System", icon='OUTLINER_OB_CURVES')
        row = layout.row(align=True)
        row.prop(settings, "preview", toggle=True, icon='HIDE_OFF' if settings.preview else 'HIDE_ON')
        row.operator("photonlm.remove_preview", text="", icon='TRASH')
        layout.operator("photonlm.export_scene_file", text="Export Scene File...", icon='EXPORT')

        if settings.last_photons:
            box = layout.box()
            box.label(text="Last Bake", icon='INFO')
            col = box.column(align=True)
            for label, prop in (("Objects", "last_objects"), ("Photons", "last_photons"), ("Time", "last_time"), ("Error", "last_error"),
                                ("Photon Speed", "last_rate"), ("Warnings", "last_warnings")):
                split = col.split(factor=0.4)
                split.alignment = 'RIGHT'
                split.label(text=label)
                split.label(text=getattr(settings, prop))


class PHOTONLM_PT_object(bpy.types.Panel):
    bl_label = "Active Object"
    bl_idname = "PHOTONLM_PT_object"
    bl_parent_id = "PHOTONLM_PT_lightmaps"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and context.active_object.type == 'MESH'

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        obj = context.active_object
        layout.label(text=obj.name, icon='OBJECT_DATA')
        layout.prop(obj.photonlm, "enabled")
        col = layout.column()
        col.enabled = obj.photonlm.enabled
        col.prop(obj.photonlm, "resolution", text="Resolution (0 = Auto)")
        col.prop(obj.photonlm, "mode")
        layout.prop(obj.photonlm, "primitive")
        ls = obj.photonlm.lsystem
        layout.prop(ls, "enabled")
        if ls.enabled:
            col = layout.column()
            col.prop(ls, "rules")
            col.prop(ls, "depth")
            col.prop(ls, "seed")
            col.prop(ls, "step")
            col.prop(ls, "width")
            col.prop(ls, "ol_level")
            col.prop(ls, "preview_cap")
            col.operator("photonlm.update_lsystem", icon='FILE_REFRESH')
        if obj.photonlm.mode != 'LIGHTMAP':
            col.prop(obj.photonlm, "ol_resolution")
        for coll in obj.users_collection:
            if coll != context.scene.collection:
                col.prop(coll.photonlm, "orientation_lightmap", text="Collection '%s': One OL" % coll.name)
        text, icon = uvmaps.status(obj)
        col.label(text=text, icon=icon)
        image = bpy.data.images.get(obj.name + "_lightmap")
        if image is not None:
            col.label(text="Lightmap: %s (%d x %d)" % (image.name, image.size[0], image.size[1]),
                      icon='IMAGE_DATA')


_CLASSES = (PHOTONLM_PT_lightmaps, PHOTONLM_PT_object)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
