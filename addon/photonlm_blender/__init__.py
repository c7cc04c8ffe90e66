"""PhotonLM: photon-lightmap global illumination baker for Blender.

The add-on is thin: it exports the evaluated scene (meshes, materials, lights,
world colour) as numpy arrays to the `photonlm` bridge, runs the native bake on
a worker thread, writes one EXR lightmap per object and wires the lightmaps
into the objects' materials behind a preview toggle. No transport math lives
in Python.

Modules
    compat      every difference of Blender's Python API between 3.4, 4.x and 5.x (the rest imports it)
    dependencies  NumPy: without it only a panel saying what is missing and how to get it is registered
    bridge      finds and imports the `photonlm` package (beside the add-on when installed)
    properties  scene / object settings and the last bake's statistics
    uvcheck     measures a lightmap UV layout as the engine uses it (overlaps, margins, map use)
    uvmaps      automatic `lightmap` UV maps made for the evaluated mesh (user maps are kept)
    csg_export  objects marked as primitives + Boolean modifiers -> exact CSG solids
    lsystem     L-system objects: presets, engine-made previews, light stored on the preview
    export      Blender scene -> photonlm.Scene (numpy, foreach_get)
    materials   reads Blender materials; wires lightmaps into node trees, preview toggle
    bake        one bake job: prepare (main thread) / run (any thread) / finish (main thread)
    operators   bpy.ops.photonlm.bake (modal with progress bar, or synchronous)
    scene_file_export  File > Export > PhotonLM scene (.json) for `photonlm bake` on batch machines
    bake_import  File > Import > PhotonLM bake folder: lightmaps baked from a scene file, brought back
    panel       Render Properties > PhotonLM Lightmaps
"""

# The add-on's version; blender_manifest.toml's `version` says the same. Blender's extension loader
# leaves bl_info out of an extension's module, so the code reads VERSION.
VERSION = (0, 1, 0)

bl_info = {
    "name": "PhotonLM Lightmaps",
    "author": "photonlm contributors",
    "version": VERSION,
    "blender": (3, 4, 0),
    "location": "Properties > Render > PhotonLM Lightmaps",
    "description": "Bakes global illumination lightmaps with photon tracing",
    "category": "Render",
}

if "bpy" in locals():  # re-running register() after a reload in the same session
    import importlib
    for _name in ("compat", "dependencies", "bridge", "properties", "uvcheck", "uvmaps", "csg_export", "lsystem",
                  "export", "materials", "bake", "operators", "scene_file_export", "bake_import", "panel"):
        if _name in locals():
            importlib.reload(locals()[_name])

import bpy  # noqa: E402  (after the reload block)

from . import compat, dependencies  # noqa: E402,F401

if dependencies.missing() is None:
    from . import bridge, properties, uvmaps, csg_export, lsystem, export, materials, bake, operators, panel  # noqa: E402,F401,E501
    from . import scene_file_export, bake_import  # noqa: E402
    _MODULES = (properties, lsystem, operators, scene_file_export, bake_import, panel)
else:  # the add-on enables and its panel says what is missing
    _MODULES = (dependencies,)


def register():
    for module in _MODULES:
        module.register()


def unregister():
    for module in reversed(_MODULES):
        module.unregister()
