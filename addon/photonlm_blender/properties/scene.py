"""Scene settings: scene.photonlm (bake settings, preview mode, and read-only views of the last
bake's statistics, which writeback/record.py keeps on the scene). How an object's lightmap size
follows from them: export/resolution.py."""
import bpy
from bpy.props import (BoolProperty, CollectionProperty, EnumProperty, FloatProperty, FloatVectorProperty, IntProperty,
                       PointerProperty, StringProperty)

from .. import bridge
from ..writeback import record, wiring

# The engine's own defaults (0 where the engine cannot be loaded: nothing bakes then). The add-on
# differs in two: it bakes to a quality (a target error, photons only a cap), not a photon count.
ENGINE = bridge.engine_defaults()
TARGET_ERROR_DEFAULT = 0.02
PHOTON_CAP_DEFAULT = 50_000_000


def _stat_getter(key, fmt):
    def get(self):
        stats = record.stats(self.id_data)
        if not stats or key not in stats:
            return ""
        try:
            return fmt(stats[key])
        except (TypeError, ValueError):
            return str(stats[key])
    return get


def _fmt_count(x):
    return "{:,}".format(int(x))


def _fmt_seconds(x):
    return "%.2f s" % float(x)


def _fmt_percent(x):
    return "%.2f %%" % (100.0 * float(x))


def _fmt_rate(x):
    x = float(x)
    if x >= 1e6:
        return "%.2f M photons/s" % (x / 1e6)
    return "%.0f k photons/s" % (x / 1e3)


def _fmt_bytes(x):
    x = float(x)
    if x >= 1e9:
        return "%.1f GB" % (x / 1e9)
    return "%.0f MB" % (x / 1e6)


def _preview_update(self, context):
    wiring.set_preview_all(self.preview_mode)


def _preview_get(self):
    return self.preview_mode != 'OFF'


def _preview_set(self, value):
    if not value:
        self.preview_mode = 'OFF'
    elif self.preview_mode == 'OFF':
        self.preview_mode = 'LIGHTMAP'


def _error_above_get(self):
    """'12.3 %': the share of covered texels above twice the target (or twice the RMS error)."""
    stats = record.stats(self.id_data)
    if not stats or "error_above" not in stats:
        return ""
    return "%.1f %%" % (100.0 * float(stats["error_above"]))


def _noisy_hint_get(self):
    """A one-line suggestion when much of the lightmap is above twice the target error ('' when not)."""
    stats = record.stats(self.id_data)
    if not stats or float(stats.get("error_above", 0.0)) <= record.NOISY_SHARE:
        return ""
    return "Lower Resolution or add time"


def _noisiest_get(self):
    """'Sphere (3.2 %)': the object with the largest relative RMS error (relative to its own mean: what
    the target error bounds), with that error."""
    stats = record.stats(self.id_data)
    if not stats or not stats.get("worst_object"):
        return ""
    return "%s (%s)" % (stats["worst_object"], _fmt_percent(float(stats.get("error_worst", 0.0))))


def _light_group_update(self, context):
    """A strength or tint set by the panel or a script: tag the scene, so that the drivers of the
    light groups' mix (which read the scene's evaluated copy) see the new value."""
    self.id_data.update_tag()


class PhotonlmLightGroup(bpy.types.PropertyGroup):
    """A light group's strength and tint in the preview (writeback/lightgroups.py): its name is the
    group's (Blender's Light Group, the layer's)."""
    strength: FloatProperty(
        name="Strength", description="How strongly this light group's baked light shows in the lightmap "
        "preview (1 = as baked, 0 = off); keyframe it to relight an animation without baking again",
        default=1.0, min=0.0, soft_max=10.0, update=_light_group_update)
    tint: FloatVectorProperty(
        name="Tint", description="A colour multiplying this light group's baked light in the lightmap preview "
        "(white = as baked)", subtype='COLOR', size=3, default=(1.0, 1.0, 1.0), min=0.0, soft_max=1.0,
        update=_light_group_update)


class PhotonlmSceneSettings(bpy.types.PropertyGroup):
    target_error: FloatProperty(
        name="Target Error", description="Relative noise to reach (0.02 = 2%): photons are traced and "
        "noisy texels get more direct-light samples until the estimated relative RMS error over all "
        "texels is this low, the time budget is spent or Max Photons are traced. 0 = trace exactly "
        "Max Photons. Halving it takes about four times as long", default=TARGET_ERROR_DEFAULT, min=0.0, max=0.5, soft_min=0.002, precision=3, step=0.1)
    time_budget: FloatProperty(
        name="Time Budget", description="Seconds the bake may take; it stops when they are spent, even above the "
        "target error (the error reached is reported); 0 = no limit",
        default=float(ENGINE.get("time_budget", 0.0)), min=0.0,
        soft_max=3600.0, unit='TIME_ABSOLUTE')
    photons: IntProperty(
        name="Max Photons", description="Photons emitted from all lights together: the cap with a target "
        "error or time budget, the exact count without (noise falls as 1/sqrt(photons); time grows in "
        "proportion, about 2-5 M photons per second and core); 0 = no cap",
        default=PHOTON_CAP_DEFAULT, min=0, soft_max=1_000_000_000)
    direct_samples: IntProperty(
        name="Direct Samples", description="Shadow-ray points per texel for direct light (more are added "
        "to noisy texels when a target error is set); time grows in proportion to samples x texels. 0 = "
        "photons carry direct light too (noisier shadows)",
        default=ENGINE.get("direct_samples", 0), min=0, max=65536, soft_max=1024)
    texel_value: EnumProperty(
        name="Texel Value", description="What a lightmap texel holds",
        items=[('CYCLES', "Like Cycles", "Direct light averaged over the texel as this Blender's Cycles "
                "bake converges to: over its central half up to Blender 4.x (sharper shadow edges), over "
                "the whole texel from 5.0"),
               ('AREA', "Texel Average", "Direct light averaged over the whole texel (smoother shadow edges)")],
        default=ENGINE.get("texel_value", 'CYCLES'))
    texel_density: IntProperty(
        name="Texel Density", description="Lightmap texels per metre for objects whose resolution is Auto "
        "(n = clamp(next power of two of sqrt(surface area) x density, 16, 4096)). Doubling it gives four "
        "times the texels: four times the memory and about four times the time to the same error",
        default=32, min=1, soft_max=1024, subtype='NONE')
    lightmap_layout: EnumProperty(
        name="Layout", description="How the baked lightmaps are stored",
        items=[('OBJECT', "One per Object", "Each object gets a lightmap image of its own, n x n with n a power "
                "of two (<object>_lightmap.exr): simplest to inspect, many files, density rounded per object"),
               ('ATLAS', "Atlases", "Objects share atlas pages (<scene>_atlas_<k>_lightmap.exr) at one texel density; "
                "each object reads its part through the UV map 'PhotonLM Atlas' (for game and web exports: few "
                "textures, few draw-call changes)")],
        default='OBJECT')
    atlas_size: EnumProperty(
        name="Page Size", description="Width and height of an atlas page in texels; an object's block (with its "
        "margin) must fit in one page, larger ones are scaled down with a warning. Larger pages mean fewer "
        "files and less space lost at page edges, but each page is loaded whole (4096: 256 MB as float RGBA)",
        items=[('512', "512", ""), ('1024', "1024", ""), ('2048', "2048", ""), ('4096', "4096", ""),
               ('8192', "8192", "")],
        default='2048')
    lightmap_margin: IntProperty(
        name="Margin", description="Texels the lightmap is extended beyond its UV islands (dilation) and, in "
        "atlases, the texels between two objects' blocks (each block's edge repeated, so that filtering never "
        "mixes two objects). More margin keeps mipmapped or compressed lightmaps seamless further away; it "
        "costs atlas space: a 32-texel block with a margin of 8 fills 40 x 40",
        default=8, min=1, max=64)
    directional: BoolProperty(
        name="Directional", default=False,
        description="Also keep the direction of each texel's light (SH L1: three more images per lightmap), so "
                    "that normal maps and bump respond to the baked light in the preview and in engines that read "
                    "directional lightmaps (Godot 4's layout). Four times the lightmap files and memory; not "
                    "with light groups, orientation lightmaps, exact shapes or L-system objects")
    output_dir: StringProperty(
        name="Output", description="Folder for the EXR lightmaps (<object>_lightmap.exr). A relative path "
        "(//) is relative to the .blend file and the images link their files relative to it, so the "
        "project folder can be moved; in an unsaved file the lightmaps are packed into it",
        default="//lightmaps/", subtype='DIR_PATH')
    pack_lightmaps: BoolProperty(
        name="Pack Lightmaps", default=False,
        description="Also pack the baked images into the .blend: one file to move or send, at the cost of a "
                    "larger .blend rewritten on every save (unsaved files always pack)")
    native_subdivision: BoolProperty(
        name="Native Subdivision", default=True,
        description="Export objects whose last modifier is a Subdivision Surface as their cage and refine "
                    "them in the engine (OpenSubdiv, the modifier's render level); off: Blender's subdivided mesh")
    max_bounces: IntProperty(
        name="Max Bounces", description="Bounces after the first hit; 0 bakes direct light only. Photons stop "
        "by Russian roulette long before the default, so lowering it saves little time and loses light",
        default=ENGINE.get("max_bounces", 0), min=0, soft_max=1024)
    seed: IntProperty(name="Seed", description="Random seed; the result depends on the seed only, "
                      "not on the number of threads", default=ENGINE.get("seed", 0), min=0)
    preview_mode: EnumProperty(
        name="Preview", description="What the materials of the baked objects show in Material Preview and "
        "Rendered view (a separate Material Output; the original nodes stay untouched)",
        items=[('OFF', "Off", "The materials as they were: the original Material Output"),
               ('LIGHTMAP', "Lightmaps", "The baked light: albedo x lightmap + emission"),
               ('ERROR', "Error", "Each texel's relative error (standard error / value) as a heat map: "
                "green up to the target error, yellow at twice it, red at four times and above")],
        default='OFF', update=_preview_update)
    live_preview: FloatProperty(
        name="Live Preview", description="While a bake runs, the viewport (Material Preview and Rendered) "
        "shows the lightmaps as they are so far, refreshed every this many seconds; cancelling puts back "
        "what was there before. 0 = off (nothing changes until the bake ends)",
        default=3.0, min=0.0, soft_max=60.0, unit='TIME_ABSOLUTE')
    preview: BoolProperty(
        name="Preview Lightmaps", description="Preview on (Lightmaps, or the Error heat map when chosen) or off; "
        "the same as Preview other than Off", get=_preview_get, set=_preview_set)
    # Read-only statistics of the last bake (stored on the scene: writeback/record.py).
    last_photons: StringProperty(name="Photons", get=_stat_getter("photons_emitted", _fmt_count))
    last_time: StringProperty(name="Time", get=_stat_getter("seconds_total", _fmt_seconds))
    last_error: StringProperty(name="Error", description="Estimated relative RMS error over all texels (each "
                               "object's own is at most the Target Error: see Noisiest)",
                               get=_stat_getter("error_estimate", _fmt_percent))
    last_error_above: StringProperty(
        name="Above 2x", description="Share of the lightmap texels whose relative error is above twice the "
        "target error (twice the RMS error without a target)", get=_error_above_get)
    last_error_p95: StringProperty(
        name="95th %", description="95th percentile of the texels' relative errors: 5 % of the texels are "
        "noisier than this", get=_stat_getter("error_p95", _fmt_percent))
    last_error_median: StringProperty(name="Median", description="Median of the texels' relative errors",
                                      get=_stat_getter("error_median", _fmt_percent))
    last_memory: StringProperty(name="Memory", description="Memory the engine estimated for the bake",
                                get=_stat_getter("memory_estimate", _fmt_bytes))
    last_hint: StringProperty(name="Hint", description="What to do when much of the lightmap is above twice "
                              "the target error: lower the Resolution of the noisiest objects, or give the bake "
                              "more time (Time Budget, Max Photons) or a lower Target Error", get=_noisy_hint_get)
    last_noisiest: StringProperty(name="Noisiest", description="The object with the largest estimated relative "
                                  "RMS error (relative to its own mean light), with that error: the Target Error "
                                  "holds for every object", get=_noisiest_get)
    last_rate: StringProperty(name="Photon Speed", description="Photons per second of the photon pass",
                              get=_stat_getter("photons_per_second", _fmt_rate))
    last_warnings: StringProperty(name="Warnings", get=_stat_getter("warning_count", _fmt_count))
    last_objects: StringProperty(name="Objects", get=_stat_getter("objects", _fmt_count))
    light_groups: CollectionProperty(
        type=PhotonlmLightGroup, name="Light Groups",
        description="The strength and tint of each light group in the lightmap preview (made by a bake with "
        "Light Groups)")


_CLASSES = (PhotonlmLightGroup, PhotonlmSceneSettings)


PREVIEW_MODE_INDEX = {'OFF': 0, 'LIGHTMAP': 1, 'ERROR': 2}  # how preview_mode is stored in a file


@bpy.app.handlers.persistent
def migrate_preview(_=None):
    """Files saved when the preview was an on/off toggle stored scene.photonlm.preview (0 / 1):
    they open with the preview mode that toggle showed (Lightmaps or Off)."""
    for scene in bpy.data.scenes:
        group = scene.get("photonlm")
        if group is None or "preview" not in group:
            continue
        if "preview_mode" not in group:
            group["preview_mode"] = PREVIEW_MODE_INDEX['LIGHTMAP' if group["preview"] else 'OFF']
        del group["preview"]


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.photonlm = PointerProperty(type=PhotonlmSceneSettings)
    if migrate_preview not in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.append(migrate_preview)


def unregister():
    if migrate_preview in bpy.app.handlers.load_post:
        bpy.app.handlers.load_post.remove(migrate_preview)
    del bpy.types.Scene.photonlm
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
