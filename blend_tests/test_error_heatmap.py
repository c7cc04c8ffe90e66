"""The error heat map: <object>_error images and the Preview = Error mode.

A floor (64 x 64) and a box (32 x 32) under a sun and a sky, baked to a 3 % target:
- each baked object has <object>_error.exr (16-bit floats) next to its lightmap, loaded as the
  float, Non-Color image <object>_error of the lightmap's size, whose R, G and B are the texel's
  relative error (the lightmap's error / its mean RGB, 0 where it has no light) to 1e-3;
- Preview = Error makes every wired material render through the heat-map output: UV Map
  'lightmap' -> the object's error image -> / (4 x target) -> colour ramp -> Emission; a
  Cycles Emit bake of the floor through that output gives, texel by texel, the ramp's colour
  for the texel's error (green up to the target, yellow at 2x, red at 4x and above);
- Lightmaps and Off switch to the lightmap output and the original output; the old boolean
  `preview` still works; a second bake keeps the mode and reuses the nodes;
- Remove Preview Nodes removes the heat-map nodes and images; lightmap images and all files stay;
- lightmaps wider than 2048 texels get a heat map of the RMS over blocks.
"""
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

TARGET = 0.03


def pixels(image):
    w, h = image.size
    px = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    return px.reshape(h, w, 4)


def ramp_colour(x):
    """The heat map's colour for relative error / (4 x target), as the Color Ramp computes it."""
    from photonlm_blender.writeback import wiring
    pos = np.array([p for p, _ in wiring.HEAT_RAMP])
    col = np.array([c for _, c in wiring.HEAT_RAMP])
    x = np.clip(x, 0.0, 1.0)
    return np.stack([np.interp(x, pos, col[:, c]) for c in range(3)], axis=-1)


def tagged(mat, role):
    return next((n for n in mat.node_tree.nodes if n.get("photonlm") == role), None)


def source(socket):
    return socket.links[0].from_node if socket.is_linked else None


def emit_bake(obj, resolution):
    """Cycles Emit bake of obj's active Material Output through its 'lightmap' UV map: (h, w, 3)."""
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False  # (no denoiser in this build: the bake would come back black)
    scene.render.bake.margin = 0
    img = bpy.data.images.new("emit_bake", resolution, resolution, alpha=True, float_buffer=True)
    nt = obj.material_slots[0].material.node_tree
    node = nt.nodes.new("ShaderNodeTexImage")
    node.image = img
    node.select = True
    nt.nodes.active = node
    vl = bpy.context.view_layer
    vl.update()
    for o in vl.objects:
        o.select_set(o == obj)
    vl.objects.active = obj
    vl.update()
    try:
        bpy.ops.object.bake(type='EMIT', use_clear=True, margin=0, uv_layer="lightmap", target='IMAGE_TEXTURES')
        return pixels(img)[..., :3].copy()
    finally:
        nt.nodes.remove(node)
        bpy.data.images.remove(img)
        obj.select_set(False)


def main():
    t_start = time.perf_counter()
    scenes.setup_paths()
    from photonlm_blender.writeback import images
    from photonlm_blender.writeback import wiring
    checks = scenes.Checks("error_heatmap")
    scene = scenes.clear_scene()
    scene.photonlm.output_dir = scenes.out_dir("heatmap") + "/"
    floor = scenes.plane("floor", scenes.diffuse_material("floor_mat", (0.7, 0.7, 0.7)), size=4.0, resolution=64)
    scenes.quads_object("box", scenes.box_quads((0.3, 0.2), 0.4, 0.4, 0.8, 0.3, 4.0 / 32, 32),
                        scenes.diffuse_material("box_mat", (0.6, 0.4, 0.3)), 32)
    scenes.add_light("sun", 'SUN', (0, 0, 5), rotation=(0.5, 0.3, 0), energy=3.0)
    scenes.set_world_color((0.3, 0.4, 0.5), 0.5)
    last = scenes.photonlm_bake(400_000, 8, seed=4, target_error=TARGET, direct_samples=8)
    print("error_heatmap: bake %.1f s, error %.2f %%, above %.1f %%" % (last["wall_seconds"],
          100 * last["stats"]["error_estimate"], 100 * last["stats"]["error_above"]))

    # -- the error images -------------------------------------------------------------------------------------------
    for name, o in sorted(last["objects"].items()):
        image = bpy.data.images.get(name + "_error")
        path = o["error_path"]
        checks.check(os.path.basename(path) == name + "_error.exr" and os.path.isfile(path)
                     and os.path.dirname(path) == os.path.dirname(o["path"]),
                     "%s: %s written next to the lightmap" % (name, os.path.basename(path)))
        checks.check(image is not None and image.is_float and image.colorspace_settings.name == 'Non-Color'
                     and tuple(image.size) == tuple(o["size"]) and bpy.path.abspath(image.filepath) == path,
                     "%s: image %s_error loaded from it (float, Non-Color, %s)" % (name, name, tuple(image.size)))
        px = pixels(image)
        value = o["rgb"].astype(np.float64).mean(axis=2)
        want = np.where(value > 0, o["error"] / np.where(value > 0, value, 1.0), 0.0)
        err = (np.abs(px[..., 0] - want) / np.maximum(want, 1e-4)).max()  # 16-bit floats: 2^-11 relative
        checks.check(err <= 1e-3 and np.array_equal(px[..., 0], px[..., 1]) and np.array_equal(px[..., 0], px[..., 2]),
                     "%s: R = G = B = error / value of every texel (largest relative difference %.2g; covered "
                     "texels: median %.1f %%, max %.0f %%)" % (name, err, 100 * np.median(want[o["coverage"] > 0]),
                                                              100 * want[o["coverage"] > 0].max()))
        covered = o["coverage"] > 0
        checks.check(o["texels_above"] == int(np.count_nonzero(want[covered] > 2 * TARGET)),
                     "%s: %d of %d texels above twice the target" % (name, o["texels_above"], o["texels"]))

    # -- Preview = Error --------------------------------------------------------------------------------------------
    s = scene.photonlm
    checks.check(s.preview_mode == 'OFF' and not s.preview, "the preview starts off")
    s.preview_mode = 'ERROR'
    wired = [m for m in bpy.data.materials if wiring.is_wired(m)]
    checks.check(sorted(m.name for m in wired) == ["box_mat", "floor_mat"], "both materials wired")
    checks.check(all(m.node_tree.get_output_node(t).get("photonlm") == "output_error"
                     for m in wired for t in ('CYCLES', 'EEVEE')), "Error: every wired material renders the heat map")
    checks.check(s.preview, "preview (bool) reads on in Error mode")
    for mat, obj in (("floor_mat", "floor"), ("box_mat", "box")):
        m = bpy.data.materials[mat]
        out = tagged(m, "output_error")
        emit = source(out.inputs['Surface'])
        mix = source(emit.inputs['Color'])
        ramp = source(mix.inputs['Color1'])
        scale = source(ramp.inputs['Fac'])
        tex = source(scale.inputs[0])
        uv = source(tex.inputs['Vector'])
        chain = [n.get("photonlm") if n is not None else None for n in (emit, mix, ramp, scale, tex, uv)]
        checks.check(chain == ["error_emission", "error_shading", "error_ramp", "error_scale", "error_image", "uv"]
                     and tex.image.name == obj + "_error" and uv.uv_map == "lightmap"
                     and abs(scale.inputs[1].default_value - 4 * TARGET) < 1e-6,
                     "%s: lightmap UVs -> %s -> / %.2f -> ramp -> Emission -> heat-map output (%s)"
                     % (mat, tex.image.name if tex else None, scale.inputs[1].default_value if scale else 0, chain))
        elements = [(round(e.position, 4), tuple(round(c, 4) for c in e.color[:3])) for e in ramp.color_ramp.elements]
        checks.check(elements == [(p, tuple(round(c, 4) for c in col)) for p, col in wiring.HEAT_RAMP],
                     "%s: ramp green to 1x, yellow at 2x, red from 4x %s" % (mat, elements))

    # What Cycles renders through the heat-map output, texel by texel (an Emit bake: seen head-on).
    o = last["objects"]["floor"]
    t0 = time.perf_counter()
    got = emit_bake(floor, 64)
    rel = pixels(bpy.data.images["floor_error"])[..., 0]
    want = ramp_colour(rel / (4 * TARGET))
    covered = o["coverage"] >= 1.0
    diff = np.abs(got - want)[covered].max(axis=-1)
    print("error_heatmap: baked mean %s, ramp mean %s" % (got[covered].mean(axis=0), want[covered].mean(axis=0)))
    print("error_heatmap: Emit bake %.1f s; |colour - ramp(error)|: median %.4f, 99th %.4f, max %.4f"
          % (time.perf_counter() - t0, np.median(diff), np.percentile(diff, 99), diff.max()))
    checks.check(np.percentile(diff, 99) < 0.02, "the floor renders the ramp's colour of each texel's error")
    share = {k: float(np.mean(v[covered])) for k, v in (("green", rel <= TARGET), ("red", rel >= 4 * TARGET))}
    green = np.array(wiring.HEAT_RAMP[0][1])
    red = np.array(wiring.HEAT_RAMP[-1][1])
    # Cycles' bake point moves up to half a texel (docs/design/texels.md), so the image is read between a texel
    # and its neighbours: only texels whose neighbours are of the same class keep its colour exactly
    # (one texel far above 4x beside green ones tints them).
    def alike(mask):
        ok = mask.copy()
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                ok &= np.roll(np.roll(mask | ~covered, dy, axis=0), dx, axis=1)
        return ok & covered
    checks.check(np.all(np.abs(got[alike(rel <= TARGET)] - green).max(axis=-1) < 0.02)
                 and np.all(np.abs(got[alike(rel >= 4.5 * TARGET)] - red).max(axis=-1) < 0.05),
                 "texels at or below the target are green (%.0f %%), 4x and above red (%.0f %%)"
                 % (100 * share["green"], 100 * share["red"]))
    scene.render.engine = scenes.eevee_engine()

    # -- the other modes ---------------------------------------------------------------------------------------------
    s.preview_mode = 'LIGHTMAP'
    checks.check(all(m.node_tree.get_output_node('EEVEE').get("photonlm") == "output" for m in wired),
                 "Lightmaps: the lightmap output")
    s.preview_mode = 'OFF'
    checks.check(all(m.node_tree.get_output_node('EEVEE').name == "Material Output" for m in wired),
                 "Off: the original output")
    s.preview = True
    checks.check(s.preview_mode == 'LIGHTMAP', "preview = True means Lightmaps")
    s.preview_mode = 'ERROR'
    s.preview = True
    checks.check(s.preview_mode == 'ERROR', "preview = True keeps Error")
    counts = {m.name: len(m.node_tree.nodes) for m in wired}
    files = sorted(os.listdir(last["output_dir"]))
    last = scenes.photonlm_bake(400_000, 8, seed=5, target_error=TARGET, direct_samples=8)
    checks.check({m.name: len(m.node_tree.nodes) for m in wired} == counts, "a second bake reuses the nodes")
    checks.check(all(m.node_tree.get_output_node('EEVEE').get("photonlm") == "output_error" for m in wired),
                 "and keeps the Error mode")
    checks.check(len([i for i in bpy.data.images if i.name.startswith("floor_error")]) == 1
                 and sorted(os.listdir(last["output_dir"])) == files, "no duplicate images or files")

    # -- removing the preview ----------------------------------------------------------------------------------------
    bpy.ops.photonlm.remove_preview()
    checks.check(not any(n.get("photonlm") is not None for m in bpy.data.materials for n in m.node_tree.nodes),
                 "Remove Preview Nodes removes every PhotonLM node, the heat map's too")
    checks.check(all(m.node_tree.get_output_node('EEVEE').name == "Material Output" for m in wired),
                 "the original outputs are active again")
    checks.check(not any(bpy.data.images.get(n + "_error") for n in last["objects"]), "the heat-map images are removed")
    checks.check(all(bpy.data.images.get(n + "_lightmap") for n in last["objects"]), "the lightmap images stay")
    checks.check(all(os.path.isfile(o["path"]) and os.path.isfile(o["error_path"]) for o in last["objects"].values()),
                 "the EXR files stay")

    # -- large lightmaps: RMS over blocks -----------------------------------------------------------------------------
    rng = np.random.default_rng(1)
    big = rng.random((4096, 4096), dtype=np.float32)
    small = images.error_image_pixels(big)
    want = np.sqrt((big.astype(np.float64) ** 2).reshape(2048, 2, 2048, 2).mean(axis=(1, 3)))
    checks.check(small.shape == (2048, 2048) and np.abs(small - want).max() < 1e-6,
                 "a 4096 x 4096 lightmap's heat map is 2048 x 2048, the RMS of 2 x 2 texels")
    checks.check(images.error_image_pixels(big[:2048, :2048]) is not None
                 and images.error_image_pixels(big[:2048, :2048]).shape == (2048, 2048), "2048 x 2048 is kept as it is")
    dark = images.relative_error(np.zeros((2, 2, 3), np.float32), np.ones((2, 2), np.float32))
    checks.check(not dark.any(), "a texel without light has relative error 0 (counted below the target)")
    residue = images.relative_error(np.full((2, 2, 3), 1e-40, np.float32), np.full((2, 2), 0.1, np.float32))
    checks.check(np.isfinite(residue).all() and residue.max() == 65504.0,
                 "a texel holding rounding residue reads the heat map's largest value, not inf or NaN")
    print("error_heatmap: %.1f s" % (time.perf_counter() - t_start))
    checks.finish()


try:
    main()
except Exception:
    import traceback
    traceback.print_exc()
    sys.exit(1)
