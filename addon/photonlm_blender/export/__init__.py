"""Blender -> photonlm.Scene: one converter per kind of data (meshes through the one mesh reader,
materials, lights, world, CSG solids, subdivision cages, L-systems) and scene.py, the whole export,
which returns a Manifest of what was sent. Reads Blender; changes nothing but L-system preview
meshes. Imports only the add-on's base modules (compat, bridge, stages)."""
