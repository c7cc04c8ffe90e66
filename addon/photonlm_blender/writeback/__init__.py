"""A finished bake brought into Blender: apply (the one write-back, for a bake here and for a bake
folder), images (EXRs, heat maps, loading), atlas (pages), wiring (the preview nodes in the
materials, with closures), lsystem (light on L-system previews) and record (the last bake's
statistics, on the scene). Imports the base modules, export/ and uv/."""
