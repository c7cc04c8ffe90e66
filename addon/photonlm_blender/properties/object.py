"""Settings of objects and collections: object.photonlm (lightmap resolution, lighting mode, exact
primitive, L-system) and collection.photonlm (one orientation lightmap for a collection)."""
import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from ..export.resolution import RESOLUTION_MAX, RESOLUTION_SOFT_MAX


class PhotonlmLSystemSettings(bpy.types.PropertyGroup):
    enabled: BoolProperty(name="L-System", description="This object is an L-system: baked from its rules",
                          default=False)
    rules: StringProperty(name="Rules", description="The L-system: axiom, productions, settings (see the "
                          "user guide)", default="")
    depth: IntProperty(name="Depth", description="Derivation steps", default=5, min=0, max=60)
    seed: IntProperty(name="Seed", description="Seed of stochastic productions", default=0, min=0)
    step: FloatProperty(name="Step", description="Length of F without a parameter (m); 0 = the rules'",
                        default=0.0, min=0.0, unit='LENGTH')
    width: FloatProperty(name="Width", description="Initial branch width (m); 0 = the rules'", default=0.0,
                         min=0.0, unit='LENGTH')
    ol_level: IntProperty(name="OL Level", description="One orientation lightmap per branch this many levels "
                          "below the root (0 = one for the whole object)", default=0, min=0, max=60)
    preview_cap: IntProperty(name="Preview Primitives", description="Most primitives in the viewport preview",
                             default=20000, min=1, max=2_000_000)


class PhotonlmObjectSettings(bpy.types.PropertyGroup):
    enabled: BoolProperty(
        name="Bake Lightmap", description="Give this object a lightmap. When off the object still blocks "
        "and reflects light but gets no lightmap", default=True)
    resolution: IntProperty(
        name="Resolution", description="Lightmap width and height in texels; 0 = Auto from the scene's "
        "texel density and the object's surface area. A bake needs about 400 bytes per texel "
        "(4096: about 7 GB, 8192: about 27 GB); a bake that does not fit in the memory free is refused",
        default=0, min=0, max=RESOLUTION_MAX, soft_max=RESOLUTION_SOFT_MAX)
    density_scale: FloatProperty(
        name="Density Scale", description="Multiplies the scene's texel density for this object when its "
        "Resolution is Auto: 2 gives twice the texels along each side (four times the texels, memory and "
        "time), 0.5 a quarter. For objects seen up close (above 1) or far away (below 1)",
        default=1.0, min=0.01, soft_min=0.125, soft_max=8.0, max=64.0, precision=3)
    mode: EnumProperty(
        name="Lighting", description="How the object's light is stored",
        items=[('LIGHTMAP', "Lightmap", "An ordinary lightmap: light per texel"),
               ('ORIENTATION', "Orientation Lightmap", "One orientation lightmap (OL) over the object: "
                "light averaged over all its surface with the same normal, whatever its complexity; "
                "resolved into its lightmap image"),
               ('BACKUP', "Lightmap + OL Backup", "An ordinary lightmap whose noisy texels lean on an "
                "orientation lightmap of the object (combined by inverse variance, bias included)"),
               ('AUTO', "Auto", "An OL when the object has more triangles than "
                "4 x its lightmap texels (too complex for its lightmap), else a "
                "lightmap")],
        default='AUTO')
    ol_resolution: IntProperty(
        name="OL Resolution", description="Orientation-lightmap bins per side; 0 = automatic (16)",
        default=0, min=0, max=1024)
    lsystem: PointerProperty(type=PhotonlmLSystemSettings)
    primitive: EnumProperty(
        name="Primitive", description="The analytic shape this object was made as (with Blender's Add > "
        "Mesh operators): traced exactly, and combined exactly through Boolean modifiers whose operands "
        "are primitives too. Size from the mesh's bounds, placement from the object's transform",
        items=[('NONE', "None", "An ordinary mesh"),
               ('SPHERE', "Sphere", "UV sphere"),
               ('BOX', "Box", "Cube"),
               ('CYLINDER', "Cylinder", "Cylinder with caps"),
               ('CONE', "Cone", "Cone with a pointed top (Radius 2 = 0) and a base cap"),
               ('TORUS', "Torus", "Torus about the object's z axis")],
        default='NONE')


class PhotonlmCollectionSettings(bpy.types.PropertyGroup):
    orientation_lightmap: BoolProperty(
        name="One Orientation Lightmap", description="Light all objects of this collection (instances "
        "and objects without lightmaps too) through one orientation lightmap shared by the whole "
        "collection", default=False)
    ol_resolution: IntProperty(
        name="OL Resolution", description="Orientation-lightmap bins per side; 0 = automatic (16)",
        default=0, min=0, max=1024)


_CLASSES = (PhotonlmLSystemSettings, PhotonlmObjectSettings, PhotonlmCollectionSettings)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Object.photonlm = PointerProperty(type=PhotonlmObjectSettings)
    bpy.types.Collection.photonlm = PointerProperty(type=PhotonlmCollectionSettings)


def unregister():
    del bpy.types.Collection.photonlm
    del bpy.types.Object.photonlm
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
