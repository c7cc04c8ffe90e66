"""Light groups: one bake, relit in the preview without baking again.

A 4 x 4 x 2.5 m room with a window in its -x wall (scenes.light_groups_room), lit by a sun through
the window and a sky (a uniform world) in Blender's Light Group "day" (sun.lightgroup = world.lightgroup = "day") and
by a point and an area lamp in "night", baked once through the add-on (32 x 32 lightmaps, 1 %):
(a) every object gets the images <object>_lightmap.day and <object>_lightmap.night (files
    <object>_lightmap.<group>.exr beside its lightmap), and day + night is its lightmap to 1e-4
    (relative, lit texels); the scene gets a strength and tint per group, and the preview reads
    the layers through the node group 'PhotonLM Light Groups';
(b) EEVEE renders (160 x 120, emission only: the preview) at day only (night strength 0), night
    only (day strength 0) and half of each agree with renders of separate bakes of those lights
    alone at those strengths (the lamps hidden; the sun hidden and the sky black; every power
    halved; bakes without light groups): the means over the lit pixels within 1 %, and on 16 x 12
    blocks within 4 % on average (the bakes' own noise); strength 1 and a white tint render as
    the plain lightmap; a tint reaches the mix;
(c) a keyframed strength (night 0 at frame 1, 1 at frame 10) reaches the mix at frame 5 without
    baking again (the driven strength in the node group is the animated value, strictly between);
(d) an orientation lightmap with light groups is refused with the engine's reason, and a light
    group the engine cannot take ("default") before the bake, by name;
(e) an atlas bake gives every page a page per layer (<page>_lightmap.day / .night) that add up to
    it, and the preview reads them;
(f) the scene-file export writes the groups ("light_groups", each light's and the world's "group"),
    and its bake by the CLI, imported as a bake folder, brings the layers in.
About a minute.
"""
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

RES = 32
SKY = (0.45, 0.6, 1.0)
BAKE = dict(photons=6_000_000, max_bounces=8, target_error=0.01)
SETTINGS = dict(direct_samples=16)
WALLS = scenes.LIGHT_GROUPS_ROOM


def build():
    scene, sun, lamp, panel = scenes.light_groups_room(RES, SKY)
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 160, 120, 100
    r.film_transparent = True
    r.image_settings.file_format = 'OPEN_EXR'
    r.image_settings.color_depth = '32'
    scene.view_settings.view_transform = 'Standard'
    scene.render.engine = scenes.eevee_engine()
    scene.eevee.taa_render_samples = 1
    scene.photonlm.preview_mode = 'LIGHTMAP'
    return scene, sun, lamp, panel


def render(name):
    """An EEVEE render of the scene: (h, w, 4) float32 linear RGBA, row 0 = bottom."""
    scene = bpy.context.scene
    path = os.path.join(scenes.out_dir("light_groups"), name + ".exr")
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(path, check_existing=False)
    w, h = image.size
    px = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    bpy.data.images.remove(image)
    return px.reshape(h, w, 4)


def pixels(image):
    w, h = image.size
    px = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    return px.reshape(h, w, 4)[..., :3]


def compare(ours, ref, what, checks, mean_limit=0.01, block_limit=0.04):
    """The means over the lit pixels of the reference within mean_limit, and 10 x 10-pixel block
    means within block_limit on average. Returns (relative difference of the means, mean block
    difference)."""
    a, b = ours[..., :3].sum(axis=-1), ref[..., :3].sum(axis=-1)
    lit = (ref[..., 3] > 0.99) & (ours[..., 3] > 0.99) & (b > 1e-3 * b.max())
    mean_diff = abs(a[lit].mean() - b[lit].mean()) / b[lit].mean()
    h, w = a.shape
    k = 10
    blocks = lambda x: np.where(lit, x, 0.0).reshape(h // k, k, w // k, k).sum(axis=(1, 3))
    count = lit.reshape(h // k, k, w // k, k).sum(axis=(1, 3))
    full = count == k * k
    ba, bb = blocks(a)[full], blocks(b)[full]
    block_diff = float(np.mean(np.abs(ba - bb) / bb))
    pixel_diff = float(np.mean(np.abs(a[lit] - b[lit]) / b[lit]))
    print("light_groups: %s: means %.4f vs %.4f (%.2f %%), blocks %.2f %%, pixels %.2f %% over %d lit pixels"
          % (what, a[lit].mean(), b[lit].mean(), 100 * mean_diff, 100 * block_diff, 100 * pixel_diff,
             np.count_nonzero(lit)))
    checks.check(mean_diff < mean_limit and block_diff < block_limit and np.count_nonzero(lit) > 0.3 * lit.size,
                 "%s: the mix renders as the separate bake (means %.2f %%, blocks %.2f %%)"
                 % (what, 100 * mean_diff, 100 * block_diff))
    return mean_diff, block_diff


def set_mix(scene, day, night, tint=(1.0, 1.0, 1.0)):
    groups = scene.photonlm.light_groups
    groups["day"].strength = day
    groups["night"].strength = night
    groups["night"].tint = tint


def check_layers(last, checks):
    """(a): the layer images and files, day + night = the lightmap."""
    from photonlm_blender.writeback import lightgroups
    worst = 0.0
    for name in WALLS:
        o = last["objects"][name]
        lm = pixels(bpy.data.images[name + "_lightmap"])
        layers = o.get("layers", {})
        ok = sorted(layers) == ["day", "night"] and all(
            os.path.isfile(layers[g]["path"]) and layers[g]["path"] == lightgroups.layer_file(o["path"], g)
            and layers[g]["image"] == "%s_lightmap.%s" % (name, g) for g in layers)
        if not checks.check(ok, "%s: images %s_lightmap.day / .night and their files" % (name, name)):
            continue
        day, night = (pixels(bpy.data.images[layers[g]["image"]]) for g in ("day", "night"))
        lit = lm.sum(axis=-1) > 1e-6 * lm.sum(axis=-1).max()
        worst = max(worst, float((np.abs(day + night - lm)[lit] / lm[lit].max(axis=-1, keepdims=True)).max()))
    print("light_groups: |day + night - lightmap| / lightmap: %.2e at most" % worst)
    checks.check(worst < 1e-4, "day + night = the lightmap to 1e-4 (%.1e)" % worst)


def check_wiring(scene, checks):
    from photonlm_blender.ui import panel
    from photonlm_blender.writeback import lightgroups
    group = bpy.data.node_groups.get(lightgroups.MIX_GROUP)
    wired = [bpy.data.materials["mat_" + n] for n in WALLS]
    ok = group is not None and all(
        any(n.get("photonlm") == "light_groups" and n.node_tree == group for n in m.node_tree.nodes) for m in wired)
    checks.check(ok, "every material's preview reads its layers through '%s'" % lightgroups.MIX_GROUP)
    checks.check([n for n, _ in panel.baked_light_groups(scene)] == ["day", "night"]
                 and all(abs(g.strength - 1.0) < 1e-9 and tuple(g.tint) == (1.0, 1.0, 1.0)
                         for g in scene.photonlm.light_groups),
                 "the scene has a strength (1) and tint (white) per group, listed in the panel")


def plain_preview(wired, on):
    """Feed each material's multiply from its lightmap image (on: as the live preview does while a
    bake runs) or from the light groups' mix again."""
    from photonlm_blender.preview import live
    for mat in wired:
        live._feed_multiply(mat, from_groups=not on)
        multiply = next(n for n in mat.node_tree.nodes if n.get("photonlm") == "multiply")
        feeding = {l.from_node.get("photonlm") for l in mat.node_tree.links if l.to_node == multiply}
        assert ("image" if on else "light_groups") in feeding, (mat.name, feeding)


def check_keyframes(scene, checks):
    """(c): an animated strength reaches the node group's driven value."""
    from photonlm_blender.writeback import lightgroups
    item = scene.photonlm.light_groups["night"]
    item.strength = 0.0
    item.keyframe_insert("strength", frame=1)
    item.strength = 1.0
    item.keyframe_insert("strength", frame=10)
    scene.frame_set(5)
    group = bpy.data.node_groups[lightgroups.MIX_GROUP]
    node = "strength night"
    driven = group.nodes[node].outputs[0].default_value
    evaluated = group.evaluated_get(bpy.context.evaluated_depsgraph_get()).nodes[node].outputs[0].default_value
    print("light_groups: frame 5: night strength %.4f, driven %.4f (evaluated %.4f)"
          % (item.strength, driven, evaluated))
    checks.check(0.05 < item.strength < 0.95 and abs(driven - item.strength) < 1e-6
                 and abs(evaluated - item.strength) < 1e-6,
                 "frame 5: the mix's night strength is the animated %.3f" % item.strength)
    scene.frame_set(10)
    checks.check(abs(group.nodes[node].outputs[0].default_value - 1.0) < 1e-6, "frame 10: strength 1")


def bake_error():
    """The error a bake reports, or "" where it finishes."""
    try:
        return "" if bpy.ops.photonlm.bake() == {'FINISHED'} else "cancelled"
    except RuntimeError as e:  # the operator's error report, raised in background mode
        return str(e)


def check_refusals(scene, checks):
    """(d): an orientation lightmap with light groups is refused with the engine's message; Auto
    gives a plain lightmap instead; Blender's Light Group "default" is refused before the bake."""
    obj = bpy.data.objects["wall_back"]
    obj.photonlm.mode = 'ORIENTATION'
    error = bake_error()
    print("light_groups: with an orientation lightmap: %s" % error)
    checks.check("light groups" in error and "orientation-lightmap groups" in error,
                 "light groups with an orientation lightmap: the bake is refused with the engine's reason")
    obj.photonlm.mode = 'AUTO'
    vl = bpy.context.view_layer
    vl.lightgroups.add(name="default")
    bpy.data.objects["lamp"].lightgroup = "default"
    error = bake_error()
    print("light_groups: with a Light Group 'default': %s" % error)
    checks.check("light group 'default' cannot be baked" in error,
                 "a Light Group called 'default' is refused before the bake, by name")


def check_atlas(scene, checks):
    """(e): an atlas bake gives each page a page per layer, and the preview reads them."""
    scene.photonlm.lightmap_layout = 'ATLAS'
    scene.photonlm.atlas_size = '512'
    last = scenes.photonlm_bake(1_000_000, 8, seed=1, target_error=0.05, **SETTINGS)
    pages = sorted({o["image"] for o in last["objects"].values()})
    worst, ok = 0.0, bool(pages)
    for page in pages:
        layers = [bpy.data.images.get("%s.%s" % (page, g)) for g in ("day", "night")]
        if any(im is None for im in layers):
            ok = False
            continue
        full = pixels(bpy.data.images[page])
        day, night = (pixels(im) for im in layers)
        lit = full.sum(axis=-1) > 1e-6 * full.sum(axis=-1).max()
        worst = max(worst, float((np.abs(day + night - full)[lit] / full[lit].max(axis=-1, keepdims=True)).max()))
    checks.check(ok and worst < 1e-4, "atlas: pages %s have a page per layer, day + night = the page (%.1e)"
                 % (pages, worst))
    mat = bpy.data.materials["mat_floor"]
    images = {n.image.name for n in mat.node_tree.nodes if str(n.get("photonlm", "")).startswith("layer_")}
    page = last["objects"]["floor"]["image"]
    checks.check(images == {page + ".day", page + ".night"}, "atlas: the floor's preview reads %s" % sorted(images))
    scene.photonlm.lightmap_layout = 'OBJECT'


def check_scene_file(checks):
    """(f): the scene-file export carries the groups: "light_groups", and "group" on lights and world."""
    import json
    from photonlm_blender.bake import scene_file
    path = os.path.join(scenes.out_dir("light_groups"), "scene.json")
    path, meta = scene_file.export_scene_file(bpy.context, path)
    doc = json.load(open(path))
    groups = {l.get("name"): l.get("group") for l in doc.get("lights", [])}
    checks.check(doc.get("light_groups") == ["day", "night"] and meta["light_groups"] == ["day", "night"]
                 and groups == {"sun": "day", "lamp": "night", "panel": "night"}
                 and doc.get("world", {}).get("group") == "day",
                 "the scene file holds the groups %s, the lights' %s and the world's" % (doc.get("light_groups"), groups))
    # Baked by the CLI and imported: the layers come in as a bake in Blender brings them.
    import subprocess
    from photonlm_blender.bake import folder
    out = os.path.join(scenes.out_dir("light_groups"), "cli_bake")
    r = subprocess.run([scenes.cli_path(), "bake", path, "-o", out], capture_output=True, text=True, timeout=600)
    if not checks.check(r.returncode == 0, "the CLI bakes the scene file (%s)" % r.stderr.strip()[-300:]):
        return
    last, _ = folder.import_folder(bpy.context, out)
    o = last["objects"]["floor"]
    images = [bpy.data.images.get(o.get("layers", {}).get(g, {}).get("image", "")) for g in ("day", "night")]
    ok = all(im is not None for im in images)
    if ok:
        full = pixels(bpy.data.images[o["image"]])
        day, night = (pixels(im) for im in images)
        ok = float(np.abs(day + night - full).max()) <= 1e-4 * float(full.max())
    checks.check(ok and last["stats"].get("light_layers") == "day,night",
                 "an imported CLI bake brings the floor's layers, which add up to its lightmap")


def main():
    t_start = time.perf_counter()
    scenes.setup_paths()
    checks = scenes.Checks("light_groups")
    scene, sun, lamp, panel_light = build()
    last = scenes.photonlm_bake(seed=1, **BAKE, **SETTINGS)
    print("light_groups: bake with groups %.1f s, error %.2f %%" % (last["wall_seconds"],
                                                                   100 * last["stats"]["error_estimate"]))
    checks.check(last["stats"].get("light_layers") == "day,night", "the bake's layers are day, night (%s)"
                 % last["stats"].get("light_layers"))
    errors = [float(e) for e in str(last["stats"].get("light_layer_errors", "")).split(",") if e]
    checks.check(len(errors) == 2 and all(0.0 < e < 1.0 for e in errors),
                 "each layer has its estimated error (%s)" % ", ".join("%.2f %%" % (100 * e) for e in errors))
    check_layers(last, checks)
    check_wiring(scene, checks)
    wired = [bpy.data.materials["mat_" + n] for n in WALLS]

    # (b) the preview's mixes
    mixes = {}
    for key, (day, night) in (("day", (1.0, 0.0)), ("night", (0.0, 1.0)), ("half", (0.5, 0.5)),
                              ("both", (1.0, 1.0))):
        set_mix(scene, day, night)
        mixes[key] = render("mix_" + key)
    set_mix(scene, 0.0, 1.0, (1.0, 0.5, 0.0))
    bpy.context.view_layer.update()
    from photonlm_blender.writeback import lightgroups
    tint = tuple(bpy.data.node_groups[lightgroups.MIX_GROUP].nodes["tint night"].outputs[0].default_value)[:3]
    checks.check(np.allclose(tint, (1.0, 0.5, 0.0)), "the night tint reaches the mix (%s)" % (tint,))
    set_mix(scene, 1.0, 1.0)
    plain_preview(wired, True)
    plain = render("plain")
    plain_preview(wired, False)
    same = float(np.abs(mixes["both"] - plain).max() / max(plain[..., :3].max(), 1e-9))
    checks.check(same < 1e-3, "strengths 1 and white tints render as the plain lightmap (%.1e)" % same)

    # separate bakes of those lights alone, without light groups
    for obj in (sun, lamp, panel_light):
        obj.lightgroup = ""
    scene.world.lightgroup = ""
    lamp.hide_render = panel_light.hide_render = True
    t0 = time.perf_counter()
    scenes.photonlm_bake(seed=2, **BAKE, **SETTINGS)
    ref_day = render("ref_day")
    lamp.hide_render = panel_light.hide_render = False
    sun.hide_render = True
    scenes.set_world_color(SKY, 0.0)
    scenes.photonlm_bake(seed=3, **BAKE, **SETTINGS)
    ref_night = render("ref_night")
    sun.hide_render = False
    scenes.set_world_color(SKY, 1.0)
    for light in (sun, lamp, panel_light):
        light.data.energy *= 0.5
    scenes.photonlm_bake(seed=4, **BAKE, **SETTINGS)
    ref_half = render("ref_half")
    print("light_groups: three reference bakes and renders %.1f s" % (time.perf_counter() - t0))
    checks.check(not any(n.get("photonlm") == "light_groups" for m in wired for n in m.node_tree.nodes),
                 "a bake without light groups wires the plain lightmap again")
    compare(mixes["day"], ref_day, "day only", checks)
    compare(mixes["night"], ref_night, "night only", checks)
    compare(mixes["half"], ref_half, "half day, half night", checks)

    # (c) and (d)
    for light in (sun, lamp, panel_light):
        light.data.energy *= 2.0
    scenes.set_world_color(SKY, 2.0)
    sun.lightgroup = scene.world.lightgroup = "day"
    lamp.lightgroup = panel_light.lightgroup = "night"
    scenes.photonlm_bake(1_000_000, 8, seed=1, target_error=0.05, **SETTINGS)
    check_keyframes(scene, checks)
    check_scene_file(checks)
    check_atlas(scene, checks)
    check_refusals(scene, checks)
    print("light_groups: %.1f s" % (time.perf_counter() - t_start))
    checks.finish()


try:
    main()
except Exception:
    import traceback
    traceback.print_exc()
    sys.exit(1)
