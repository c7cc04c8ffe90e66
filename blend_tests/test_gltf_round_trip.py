"""Round trip of a .glb with lightmaps: File > Import > glTF with PhotonLM lightmaps brings the exported
scene back into an empty scene (Blender's glTF importer, then each material's lightmap decoded from the
file's RGBM PNG and wired into the lightmap preview), and it renders as the scene it came from.

The Cornell box (Principled BSDFs of the boxes' colours, which the exporter writes as base colours),
baked with the add-on, exported, rendered in EEVEE with the lightmap preview (Standard view transform,
the world black, the lights off: the light is the lightmap's); then a new empty scene with the same
camera, the file imported with PhotonLM's import, rendered alike. Expected: every baked object comes
back wired to a lightmap image that equals its EXR within the RGBM encoding's bound, and the two
renders' mean relative difference on the lit pixels within 1 % (the encoding's 0.4 % at most per
texel, and the renderers' look-ups of the same texels). A file without lightmaps is refused by name.
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

WIDTH, HEIGHT = 160, 120


def render(path):
    """The lightmap preview (scenes.render_lightmap_preview) as a float EXR: (h, w, 3) linear."""
    r = bpy.context.scene.render
    r.image_settings.file_format = 'OPEN_EXR'
    r.image_settings.color_depth = '32'
    scenes.render_lightmap_preview(path, WIDTH, HEIGHT)
    return scenes.exr_rgb(path)


def main():
    checks = scenes.Checks("gltf_round_trip")
    scenes.enable_gltf_addons()
    out = scenes.out_dir("gltf_round_trip")
    scenes.clear_scene()
    objs = scenes.cornell_box(resolution=16)
    objs.pop("light")
    scenes.cornell_camera()
    scenes.principled_materials()
    bpy.context.scene.photonlm.output_dir = out
    last = scenes.photonlm_bake(2_000_000, 16, seed=5, target_error=0.02)
    original = render(os.path.join(out, "original.exr"))
    from photonlm_blender.gltf.export import export_glb
    path = os.path.join(out, "cornell.glb")
    export_glb(bpy.context, path)

    camera = bpy.context.scene.camera
    bpy.ops.scene.new(type='EMPTY')
    bpy.context.scene.collection.objects.link(camera)
    bpy.context.scene.camera = camera
    before = set(bpy.data.objects)
    res = bpy.ops.photonlm.import_gltf(filepath=path)
    new = {o.name.rsplit(".", 1)[0] if o.name not in objs else o.name: o
           for o in bpy.data.objects if o not in before and o.type == 'MESH'}
    checks.check(res == {'FINISHED'} and sorted(new) == sorted(objs),
                 "File > Import > glTF with PhotonLM lightmaps brings %d objects back (%s)" % (len(new), res))
    worst = 0.0
    for name, obj in new.items():
        mat = obj.active_material
        tex = [n for n in mat.node_tree.nodes if n.bl_idname == 'ShaderNodeTexImage' and n.image is not None
               and n.image.name.startswith(name + "_lightmap")] if mat is not None else []
        if not tex:
            checks.check(False, "'%s': its material reads a lightmap image" % name)
            continue
        image = tex[0].image
        w, h = image.size
        px = np.empty(w * h * 4, np.float32)
        image.pixels.foreach_get(px)
        exr = scenes.exr_rgb(last["objects"][name]["path"])
        info = mat["photonlm_lightmap"]
        diff = np.abs(px.reshape(h, w, 4)[..., :3] - exr)
        bound = float(info["range"]) / 510.0 * (1 + 1e-5)  # the encoding's m range / 510, m <= 1
        worst = max(worst, float(diff.max() / bound))
    checks.check(0.0 < worst <= 1.0, "every imported lightmap image equals its EXR within the RGBM bound "
                 "(worst |diff| / (range / 510) = %.3f)" % worst)
    imported = render(os.path.join(out, "imported.exr"))
    lit = (original.max(axis=2) > 0.02) & (imported.max(axis=2) > 0.02)
    rel = np.abs(imported - original).mean(axis=2)[lit] / original.mean(axis=2)[lit]
    mean = float(rel.mean()) if lit.any() else math.inf
    checks.check(lit.sum() > 0.5 * WIDTH * HEIGHT and mean <= 0.01,
                 "the imported scene renders as the original: mean relative difference %.3f %% on %d lit pixels"
                 % (100 * mean, int(lit.sum())))

    empty = os.path.join(out, "plain.glb")
    bpy.ops.export_scene.gltf(filepath=empty, export_format='GLB')
    try:
        res = bpy.ops.photonlm.import_gltf(filepath=empty)
    except RuntimeError as e:
        res = str(e)
    checks.check("carries no PhotonLM lightmap" in str(res), "a file without lightmaps is refused (%s)" % res)
    checks.finish()


main()
