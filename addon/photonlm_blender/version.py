"""The add-on's version; blender_manifest.toml's `version` says the same. Blender's extension loader
leaves bl_info out of an extension's module, so the code reads VERSION."""
VERSION = (0, 1, 0)
