"""PhotonLM: photon-lightmap global illumination baker for Blender.

The add-on is thin: it exports the evaluated scene (meshes, materials, lights,
world colour) as numpy arrays to the `photonlm` bridge, runs the native bake on
a worker thread, writes one EXR lightmap per object and wires the lightmaps
into the objects' materials behind a preview toggle. No transport math lives
in Python.

Packages, from the bottom up (each imports only from those below it and from
its own package; nothing imports upwards):
    compat, version, dependencies, bridge, stages   what differs between Blender versions, the version,
                    the NumPy check, finding the `photonlm` package, stage timing
    export/         Blender -> photonlm.Scene, one converter per kind of data: meshes (the one mesh
                    reader), materials + flatten, lights, world, csg, subdiv, lsystem, resolution,
                    lightgroups (Blender's Light Groups -> the engine's), scene (the whole export; it
                    returns a Manifest of what was sent)
    uv/             lightmap UV maps (uvmaps), their measures (uvcheck), atlas packing (atlas_pack)
    writeback/      a result -> Blender: apply (the one write-back), images (EXRs, heat maps),
                    atlas pages, material wiring and its preview closures, the light groups' mix,
                    directional lightmaps' bands and their node group, L-system light, record
                    (the last bake's statistics, on the scene)
    bake/           one bake run here (job), a bake folder from a farm (folder), a scene file
                    for batch machines (scene_file)
    gltf/           a .glb with the lightmaps through Blender's glTF exporter (export), their
                    8-bit encoding (rgbm), and such a file imported with its lightmaps (rewire)
    preview/        the lightmaps shown while a bake runs (live)
    properties/     scene and object settings
    operators/      bake, remove preview, L-system, scene-file export, bake-folder import, glTF export
    ui/             Render Properties > PhotonLM Lightmaps
"""

from .version import VERSION  # noqa: F401  (the add-on's version: blender_manifest.toml says the same)

# Blender's add-on list reads bl_info from the source as a literal (ast.literal_eval): no names in it.
bl_info = {
    "name": "PhotonLM Lightmaps",
    "author": "photonlm contributors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > PhotonLM Lightmaps",
    "description": "Bakes global illumination lightmaps with photon tracing",
    "category": "Render",
}

# Every module of the add-on in import order (a module after those it imports). register() runs the
# register() of those that have one, in this order (dependencies' only without NumPy); unregister()
# the reverse. After a reload (F8, disabling and enabling the add-on) each of them is reloaded
# first, in this order, and register() then registers the reloaded classes.
MODULE_NAMES = (
    "version", "compat", "dependencies", "bridge", "stages",
    "export.meshes", "export.resolution", "export.flatten", "export.materials", "export.lights",
    "export.world", "export.csg", "export.subdiv", "export.lsystem", "export.lightgroups", "export.scene",
    "uv.uvcheck", "uv.atlas_pack", "uv.uvmaps",
    "writeback.record", "writeback.images", "writeback.closures", "writeback.lightgroups", "writeback.directional",
    "writeback.wiring",
    "writeback.atlas",
    "writeback.lsystem", "writeback.apply",
    "gltf.rgbm", "gltf.export", "gltf.rewire",
    "bake.job", "bake.folder", "bake.scene_file",
    "preview.live",
    "properties.object", "properties.scene",
    "operators.bake", "operators.lsystem", "operators.export_scene_file", "operators.import_folder",
    "operators.export_gltf",
    "operators.import_gltf",
    "ui.panel",
)
# What runs without NumPy: a panel saying what is missing and how to get it.
BASE_MODULE_NAMES = ("version", "compat", "dependencies")

if "_modules" in locals():  # re-running register() after a reload in the same session
    import importlib
    for _module in _modules():  # noqa: F821 (defined below, kept from the first run)
        importlib.reload(_module)

import importlib  # noqa: E402  (after the reload block)

from . import dependencies  # noqa: E402


def _names():
    return MODULE_NAMES if dependencies.missing() is None else BASE_MODULE_NAMES


def _modules():
    """The add-on's modules (imported), in MODULE_NAMES order."""
    return [importlib.import_module("." + name, __name__) for name in _names()]


_modules()

if dependencies.missing() is None:
    # Blender's glTF exporter looks for this name in every enabled add-on's module.
    from .gltf.export import GltfHook as glTF2ExportUserExtension  # noqa: E402,F401


def _registered():
    """The modules whose register() runs: without NumPy only dependencies' (its panel says what is
    missing), else every module's but that one."""
    if dependencies.missing() is not None:
        return [dependencies]
    return [m for m in _modules() if hasattr(m, "register") and m is not dependencies]


def register():
    for module in _registered():
        module.register()


def unregister():
    for module in reversed(_registered()):
        module.unregister()
