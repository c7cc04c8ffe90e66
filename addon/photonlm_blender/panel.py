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
        col.prop(settings, "pack_lightmaps")

        row = layout.row()
        row.scale_y = 1.5
        running = operators._running is not None
        row.operator("photonlm.bake", icon='RENDER_STILL',
                     text="Baking... (Esc to cancel)" if running else "Bake Lightmaps")
        if not running:
            layout.operator("photonlm.bake", text="Bake Selected", icon='RESTRICT_SELECT_OFF').selected_only = True
        if bridge.error():
            layout.label(text=bridge.error(), icon='ERROR')
        layout.operator_menu_enum("photonlm.add_lsystem", "preset", text="Add L-System", icon='OUTLINER_OB_CURVES')
        col = layout.column(align=True)
        col.use_property_split = False
        col.label(text="Viewport Preview")
        row = col.row(align=True)
        row.prop(settings, "preview_mode", expand=True)
        row.operator("photonlm.remove_preview", text="", icon='TRASH')
        if settings.preview_mode == 'ERROR':
            col.label(text=_heat_legend(context.scene))
        layout.operator("photonlm.export_scene_file", text="Export Scene File...", icon='EXPORT')

        if settings.last_photons:
            box = layout.box()
            box.label(text="Last Bake", icon='INFO')
            col = box.column(align=True)
            stats = _stats(context.scene)
            rows = [("Objects", "last_objects"), ("Photons", "last_photons"), ("Time", "last_time"),
                    ("Error", "last_error")]
            if "error_above" in stats:
                rows += [("Above %.3g %%" % (200.0 * float(stats.get("error_target", 0.0))), "last_error_above"),
                         ("Percentile 95", "last_error_p95")]
            if settings.last_hint:
                rows.append(("Noisiest", "last_noisiest"))
            rows += [("Memory", "last_memory"), ("Photon Speed", "last_rate"), ("Warnings", "last_warnings")]
            for label, prop in rows:
                value = getattr(settings, prop)
                if not value:
                    continue
                split = col.split(factor=0.4)
                split.alignment = 'RIGHT'
                split.label(text=label)
                split.label(text=value + _suffix(stats, prop))
            if settings.last_hint:
                box.label(text=settings.last_hint, icon='ERROR')


def _stats(scene):
    from .properties import STATS_KEY
    return scene.get(STATS_KEY) or {}


def _suffix(stats, prop):
    """What a Last Bake figure is measured against."""
    if prop == "last_error" and float(stats.get("target_error", 0.0)) > 0.0:
        return "  (target %.3g %%)" % (100.0 * float(stats["target_error"]))
    if prop == "last_error_above":
        return " of texels"
    return ""


def _heat_legend(scene):
    """The heat map's colours in words, at the last bake's target error."""
    target = float(_stats(scene).get("error_target", 0.0)) or scene.photonlm.target_error
    return "Green \u2264%.3g%%  yellow %.3g%%  red \u2265%.3g%%" % (100.0 * target, 200.0 * target, 400.0 * target)


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
        col.prop(obj.photonlm, "resolution")
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
                col.prop(coll.photonlm, "orientation_lightmap", text="One OL: %s" % coll.name)
        text, icon = uvmaps.status(obj)
        col.label(text=text, icon=icon)
        image = bpy.data.images.get(obj.name + "_lightmap")
        if image is not None:
            col.label(text="Lightmap %d x %d" % (image.size[0], image.size[1]),
                      icon='IMAGE_DATA')


_CLASSES = (PHOTONLM_PT_lightmaps, PHOTONLM_PT_object)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
