"""Render Properties > PhotonLM Lightmaps: the quality and the bake buttons first, with the
progress bar while a bake runs; the rest in sub-panels (advanced ones closed), and the status
bar's progress bar."""
import textwrap
import time

import bpy

from .. import bridge
from ..operators import bake as bake_operator
from ..uv import uvmaps
from ..writeback import record


class _Sub:
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"
    bl_parent_id = "PHOTONLM_PT_lightmaps"


def _split_layout(layout):
    layout.use_property_split = True
    layout.use_property_decorate = False
    return layout


class PHOTONLM_PT_lightmaps(bpy.types.Panel):
    bl_label = "PhotonLM Lightmaps"
    bl_idname = "PHOTONLM_PT_lightmaps"
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    bl_context = "render"

    def draw(self, context):
        layout = _split_layout(self.layout)
        settings = context.scene.photonlm
        col = layout.column()
        col.prop(settings, "target_error", text="Target Error")
        col.prop(settings, "time_budget", text="Time Budget")

        running = bake_operator.running() is not None
        col = layout.column(align=True)
        row = col.row(align=True)
        row.scale_y = 1.5
        row.operator("photonlm.bake", icon='RENDER_STILL',
                     text="Baking... (Esc to cancel)" if running else "Bake Lightmaps")
        row = col.row(align=True)
        row.enabled = not running
        row.operator("photonlm.bake", text="Bake Selected", icon='RESTRICT_SELECT_OFF').selected_only = True
        if running:
            draw_progress(layout, context)
        if bridge.error():
            for line in wrap(bridge.error(), context):
                layout.label(text=line, icon='ERROR')
        col = layout.column(align=True)
        col.use_property_split = False
        col.label(text="Viewport Preview")
        row = col.row(align=True)
        row.prop(settings, "preview_mode", expand=True)
        row.operator("photonlm.remove_preview", text="", icon='TRASH')
        col.prop(settings, "live_preview", text="Refresh While Baking")
        if settings.preview_mode == 'ERROR':
            col.label(text=_heat_legend(context.scene))


def baked_light_groups(scene):
    """The light groups of the last bake that have settings: [(layer name, settings)]."""
    names = [n for n in str(_stats(scene).get("light_layers", "")).split(",") if n]
    groups = scene.photonlm.light_groups
    return [(n, groups[n]) for n in names if groups.get(n) is not None]


class PHOTONLM_PT_light_groups(_Sub, bpy.types.Panel):
    """The strength and tint of each light group in the preview (keyframe them to relight an
    animation without baking again)."""
    bl_label = "Light Groups"
    bl_idname = "PHOTONLM_PT_light_groups"

    @classmethod
    def poll(cls, context):
        return bool(baked_light_groups(context.scene))

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = False
        col = layout.column(align=True)
        errors = [e for e in str(_stats(context.scene).get("light_layer_errors", "")).split(",") if e]
        names = [n for n in str(_stats(context.scene).get("light_layers", "")).split(",") if n]
        error_of = dict(zip(names, (float(e) for e in errors))) if len(errors) == len(names) else {}
        for name, item in baked_light_groups(context.scene):
            row = col.row(align=True)
            split = row.split(factor=0.3)
            label = "Other Lights" if name == "default" else name
            if name in error_of:  # the layer's estimated error, as the bake's under Last Bake
                label += " (%.1f %%)" % (100.0 * error_of[name])
            split.label(text=label, icon='LIGHT')
            sub = split.row(align=True)
            sub.prop(item, "strength", text="")
            sub.prop(item, "tint", text="")


class PHOTONLM_PT_last_bake(_Sub, bpy.types.Panel):
    bl_label = "Last Bake"
    bl_idname = "PHOTONLM_PT_last_bake"

    @classmethod
    def poll(cls, context):
        return bool(context.scene.photonlm.last_photons)

    def draw(self, context):
        layout = self.layout
        settings = context.scene.photonlm
        col = layout.column(align=True)
        stats = _stats(context.scene)
        rows = [("Objects", "last_objects"), ("Photons", "last_photons"), ("Time", "last_time"),
                ("Error", "last_error")]
        if "error_above" in stats and float(stats.get("error_target", 0.0)) > 1e-9:  # not for an exact bake
            rows += [("Above %.3g %%" % (200.0 * float(stats.get("error_target", 0.0))), "last_error_above"),
                     ("Percentile 95", "last_error_p95")]
        rows.append(("Noisiest", "last_noisiest"))
        rows += [("Memory", "last_memory"), ("Photon Speed", "last_rate"), ("Warnings", "last_warnings")]
        for label, prop in rows:
            value = getattr(settings, prop)
            if not value:
                continue
            split = col.split(factor=0.45)
            split.alignment = 'RIGHT'
            split.label(text=label)
            split.label(text=value + _suffix(stats, prop))
        if settings.last_hint:
            layout.label(text=settings.last_hint, icon='ERROR')
        if stats.get("imported_from"):
            for i, line in enumerate(wrap("Imported from %s" % stats["imported_from"], context, indent=2)):
                layout.label(text=line, icon='IMPORT' if i == 0 else 'BLANK1')


class PHOTONLM_PT_warnings(_Sub, bpy.types.Panel):
    bl_label = "Warnings"
    bl_idname = "PHOTONLM_PT_warnings"
    bl_parent_id = "PHOTONLM_PT_last_bake"

    @classmethod
    def poll(cls, context):
        return bool(_stats(context.scene).get("warning_lines"))

    def draw(self, context):
        col = self.layout.column(align=True)
        for text in str(_stats(context.scene)["warning_lines"]).split("\n"):
            for i, line in enumerate(wrap(text, context, indent=2)):
                col.label(text=line, icon='ERROR' if i == 0 else 'BLANK1')


# The Last Bake's stages: (label, statistic, indented under the one before).
TIME_ROWS = (("Export", "seconds_export", False), ("Checks", "seconds_export_checks", True),
             ("UV Maps", "seconds_export_uv", True), ("Cages", "seconds_export_cages", True),
             ("Depsgraph", "seconds_export_depsgraph", True), ("Meshes", "seconds_export_meshes", True),
             ("Refinement", "seconds_export_refine", True),
             ("Materials", "seconds_export_materials", True), ("World", "seconds_export_world", True),
             ("Engine", "seconds_total", False), ("Set-up", "seconds_setup", True),
             ("Photons", "seconds_trace", True), ("Direct", "seconds_direct", True),
             ("Reading Folder", "seconds_import", False), ("Write-back", "seconds_writeback", False))


class PHOTONLM_PT_last_times(_Sub, bpy.types.Panel):
    """Where the last bake's time went: the export's stages, the engine's and the write-back."""
    bl_label = "Times"
    bl_idname = "PHOTONLM_PT_last_times"
    bl_parent_id = "PHOTONLM_PT_last_bake"
    bl_options = {'DEFAULT_CLOSED'}

    @classmethod
    def poll(cls, context):
        return "seconds_writeback" in _stats(context.scene)

    def draw(self, context):
        stats = _stats(context.scene)
        col = self.layout.column(align=True)
        triangles = int(stats.get("triangles", 0))
        for label, key, indent in TIME_ROWS:
            if key not in stats:
                continue
            split = col.split(factor=0.45)
            split.alignment = 'RIGHT'
            split.label(text=("   " if indent else "") + label)
            text = "%.2f s" % float(stats[key])
            if key == "seconds_export" and triangles:
                text += "  (%s triangles)" % short_count(triangles)
            split.label(text=text)


class PHOTONLM_PT_sampling(_Sub, bpy.types.Panel):
    bl_label = "Sampling"
    bl_idname = "PHOTONLM_PT_sampling"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = _split_layout(self.layout)
        settings = context.scene.photonlm
        col = layout.column()
        row = col.row(align=True)
        row.prop(settings, "photons", text="Max Photons")
        row.label(text=short_count(settings.photons))
        col.prop(settings, "direct_samples", text="Direct Samples")
        col.prop(settings, "max_bounces", text="Max Bounces")
        col.prop(settings, "texel_value", text="Texel Value")
        col.prop(settings, "seed")


class PHOTONLM_PT_output(_Sub, bpy.types.Panel):
    bl_label = "Lightmaps"
    bl_idname = "PHOTONLM_PT_output"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = _split_layout(self.layout)
        settings = context.scene.photonlm
        col = layout.column()
        col.prop(settings, "texel_density", text="Texels / m")
        col.prop(settings, "lightmap_layout", text="Layout")
        sub = col.column()
        sub.active = settings.lightmap_layout == 'ATLAS'
        sub.prop(settings, "atlas_size", text="Page Size")
        col.prop(settings, "lightmap_margin", text="Margin")
        col.prop(settings, "directional", text="Directional")
        col.prop(settings, "native_subdivision", text="Engine Subdivision")
        col.prop(settings, "output_dir", text="Folder")
        col.prop(settings, "pack_lightmaps", text="Pack")
        row = layout.row(align=True)
        row.operator("photonlm.export_scene_file", text="Export Scene File...", icon='EXPORT')
        row.operator("photonlm.import_bake_folder", text="Import Bake Folder...", icon='IMPORT')


def short_count(n):
    """50000000 -> '50 M': the size of a count that the field shows without separators."""
    n = int(n)
    if n == 0:
        return "no cap"
    for scale, unit in ((1e9, "G"), (1e6, "M"), (1e3, "k")):
        if n >= scale:
            return "%.3g %s" % (n / scale, unit)
    return "{:,}".format(n)


def wrap(text, context, indent=0):
    """text in lines that fit the region's width (Blender's labels do not wrap)."""
    width = context.region.width if getattr(context, "region", None) is not None else 300
    chars = max(20, int(width / (7.0 * bpy.context.preferences.view.ui_scale)) - 6)
    return textwrap.wrap(text, chars, subsequent_indent=" " * indent) or [""]


def draw_progress(layout, context):
    """The running bake's progress bar (a read-only percentage) and its stage and time left."""
    op = bake_operator.running()
    wm = context.window_manager
    col = layout.column(align=True)
    col.use_property_split = False
    col.prop(wm, "photonlm_progress", text="", slider=True)
    if op is not None:
        col.label(text=bake_operator.progress_text(op._fraction, op._stage, time.perf_counter() - op._t0))


def draw_status_bar(self, context):
    """In the status bar while a bake runs: the same progress bar."""
    if bake_operator.running() is None:
        return
    row = self.layout.row(align=True)
    row.label(text="PhotonLM")
    sub = row.row(align=True)
    sub.ui_units_x = 8
    sub.prop(context.window_manager, "photonlm_progress", text="", slider=True)


def _stats(scene):
    return record.stats(scene)


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


class PHOTONLM_PT_object(_Sub, bpy.types.Panel):
    bl_label = "Active Object"
    bl_idname = "PHOTONLM_PT_object"

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and context.active_object.type == 'MESH'

    def draw(self, context):
        layout = _split_layout(self.layout)
        obj = context.active_object
        layout.label(text=obj.name, icon='OBJECT_DATA')
        layout.prop(obj.photonlm, "enabled")
        col = layout.column()
        col.enabled = obj.photonlm.enabled
        col.prop(obj.photonlm, "resolution", text="Resolution")
        sub = col.column()
        sub.active = obj.photonlm.resolution == 0
        sub.prop(obj.photonlm, "density_scale", text="Density Scale")
        col.prop(obj.photonlm, "mode")
        if obj.photonlm.mode != 'LIGHTMAP':
            col.prop(obj.photonlm, "ol_resolution", text="OL Bins")
        for coll in obj.users_collection:
            if coll != context.scene.collection:
                col.prop(coll.photonlm, "orientation_lightmap", text="One OL: %s" % coll.name)
        text, icon = uvmaps.status(obj)
        for i, line in enumerate(wrap(text, context, indent=2)):
            col.label(text=line, icon=icon if i == 0 else 'BLANK1')
        image = bpy.data.images.get(obj.name + "_lightmap")
        if context.scene.photonlm.lightmap_layout == 'ATLAS' and obj.get("photonlm_atlas_page"):
            block = (context.scene.get("photonlm_atlas") or {}).get("blocks", {}).get(obj.name)
            if block is not None:
                col.label(text="Atlas %s: %d x %d" % (obj["photonlm_atlas_page"], block[3], block[4]),
                          icon='IMAGE_DATA')
        elif image is not None:
            col.label(text="Lightmap %d x %d" % (image.size[0], image.size[1]), icon='IMAGE_DATA')


class PHOTONLM_PT_special(_Sub, bpy.types.Panel):
    bl_label = "Exact Shapes and L-Systems"
    bl_idname = "PHOTONLM_PT_special"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        col = layout.column(align=True)
        for line in wrap("Primitive: trace a sphere, cylinder, cone or torus made with Add > Mesh as its exact "
                         "shape (smooth light, no facets). L-System: grow plants and fractals from rules, "
                         "traced without making their triangles.", context):
            col.label(text=line)
        obj = context.active_object
        if obj is not None and obj.type == 'MESH':
            sub = _split_layout(layout.column())
            sub.prop(obj.photonlm, "primitive")
            ls = obj.photonlm.lsystem
            sub.prop(ls, "enabled", text="L-System")
            if ls.enabled:
                for name in ("rules", "depth", "seed", "step", "width", "ol_level", "preview_cap"):
                    sub.prop(ls, name)
                sub.operator("photonlm.update_lsystem", icon='FILE_REFRESH')
        layout.operator_menu_enum("photonlm.add_lsystem", "preset", text="Add L-System", icon='OUTLINER_OB_CURVES')


_CLASSES = (PHOTONLM_PT_lightmaps, PHOTONLM_PT_light_groups, PHOTONLM_PT_last_bake, PHOTONLM_PT_warnings, PHOTONLM_PT_last_times,
            PHOTONLM_PT_sampling,
            PHOTONLM_PT_output, PHOTONLM_PT_object, PHOTONLM_PT_special)


def _progress_get(self):
    op = bake_operator.running()
    return 100.0 * min(max(op._fraction, 0.0), 1.0) if op is not None else 0.0


def register():
    bpy.types.WindowManager.photonlm_progress = bpy.props.FloatProperty(
        name="Bake Progress", description="How much of the running bake is done", subtype='PERCENTAGE',
        min=0.0, max=100.0, precision=0, get=_progress_get)
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.STATUSBAR_HT_header.append(draw_status_bar)


def unregister():
    bpy.types.STATUSBAR_HT_header.remove(draw_status_bar)
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
    del bpy.types.WindowManager.photonlm_progress
