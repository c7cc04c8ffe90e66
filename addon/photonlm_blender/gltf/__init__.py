"""glTF files with the baked lightmaps: Blender's own glTF exporter plus a hook that gives each
baked object's material its lightmap (export), and the lightmap's 8-bit encoding (rgbm)."""
