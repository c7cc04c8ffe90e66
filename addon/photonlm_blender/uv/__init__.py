"""Lightmap UV maps: the automatic maps made for objects without one of the user's (uvmaps), how a
layout measures as the engine uses it (uvcheck), and packing lightmaps into atlas pages
(atlas_pack). Imports the base modules and export/."""
