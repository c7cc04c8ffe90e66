"""Live preview: while a modal bake runs, the viewport shows the lightmaps as they are so far
(scene.photonlm.live_preview seconds between refreshes). Like test_modal_operator.py, this
script (started by CTest with -b) re-runs itself in a windowed Blender under xvfb-run, where
the modal operator runs, and checks what the child reports. Without xvfb-run it prints SKIP.

In the window, on the Cornell box (the add-on copies previews only while a viewport shows
materials: checked first, then it is told so, the viewport staying in Solid shading):
  1. a bake cancelled after its first refresh, before any bake: the materials are exactly as
     before (no preview nodes, same outputs active) and no image or material is left behind;
  2. a bake with previews off (the reference) and the same bake with previews every 0.3 s:
     during the second, the live images refresh at least twice, their pixels change, are
     finite and near the final answer's mean, and the materials show them; its final
     lightmap images equal the reference's bit for bit, and the live images are gone;
  3. a bake cancelled after a refresh, over the lightmaps of 2.: images (pixels), node trees
     and the set of images and materials are exactly as before.
"""
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

PHOTONS = 6_000_000
INTERVAL = 0.3
WATCHED = ("floor", "back", "left")  # walls whose lightmap covers the whole image


def parent():
    checks = scenes.Checks("live_preview")
    r = scenes.run_windowed(checks, "live_preview", __file__, timeout=600)
    if r is None:
        return
    checks.check(not r["watched_solid"] and r["watched_material"],
                 "previews are wanted in Material Preview, not in Solid shading")
    # 1. cancelled before any bake
    checks.check(r["fresh_refreshed"], "first cancelled bake showed a live preview before the cancel")
    checks.check(r["fresh_wired_live"], "  ... its materials showed the live images")
    checks.check(r["fresh_restored"], "cancel before any bake: materials exactly as before (%s)"
                 % r.get("fresh_diff", ""))
    checks.check(r["fresh_no_new_data"], "  ... and no new images or materials (%s)" % r.get("fresh_new", ""))
    # 2. a live bake
    refreshes = r["refreshes"]
    checks.check(len(refreshes) >= 2, "live bake refreshed the viewport %d times" % len(refreshes))
    checks.check(r["pixels_changed"], "the live images' pixels changed between refreshes")
    checks.check(r["all_finite"], "the live images' pixels are finite and not negative")
    checks.check(r["wired_live"], "while baking the materials show the live images (Lightmaps output active)")
    for name in WATCHED:
        final = r["final_means"][name]
        lit = [m[name] for p, m in refreshes if p > 0]
        checks.check(bool(lit) and all(0.5 * final < m < 1.5 * final for m in lit),
                     "%s: live means %s near the final mean %.4f (within 50%%)"
                     % (name, ["%.4f" % m for m in lit], final))
        checks.check(bool(lit) and abs(lit[-1] - final) < 0.1 * final,
                     "%s: the last live mean %.4f within 10%% of the final %.4f"
                     % (name, lit[-1] if lit else float("nan"), final))
    checks.check(r["final_equal"], "the live bake's lightmaps equal those of a bake without previews (bit for bit)")
    checks.check(r["live_images_gone"], "no live image is left after the bake")
    checks.check(r["final_wired"], "the materials show the final lightmap images")
    # 3. cancelled over existing lightmaps
    checks.check(r["second_refreshed"], "second cancelled bake showed a live preview before the cancel")
    checks.check(r["second_restored"], "cancel over earlier lightmaps: node trees as before (%s)"
                 % r.get("second_diff", ""))
    checks.check(r["second_pixels"], "  ... the lightmap images' pixels as before")
    checks.check(r["second_no_new_data"], "  ... no new images or materials (%s)" % r.get("second_new", ""))
    checks.finish()


# ---- the windowed child ---------------------------------------------------------------------

def fingerprint():
    """Every material's node tree: nodes (kind, image, active output), links and the ID
    properties the preview uses."""
    out = {}
    for mat in bpy.data.materials:
        tree = mat.node_tree
        if tree is None:
            out[mat.name] = None
            continue
        nodes = sorted((n.name, n.bl_idname, n.image.name if getattr(n, "image", None) else "",
                        bool(getattr(n, "is_active_output", False)), n.parent.name if n.parent else "")
                       for n in tree.nodes)
        links = sorted((l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier)
                       for l in tree.links)
        out[mat.name] = dict(nodes=[list(n) for n in nodes], links=[list(l) for l in links],
                             keys=sorted((k, str(tree[k])) for k in tree.keys()))
    return out


def data_names():
    return dict(images=sorted(i.name for i in bpy.data.images), materials=sorted(m.name for m in bpy.data.materials),
                node_groups=sorted(g.name for g in bpy.data.node_groups))


def diff(a, b):
    """A short description of what differs between two fingerprints."""
    for k in sorted(set(a) | set(b)):
        if a.get(k) != b.get(k):
            return "material %s: %s -> %s" % (k, str(a.get(k))[:300], str(b.get(k))[:300])
    return ""


def pixels(image):
    px = np.empty(image.size[0] * image.size[1] * 4, np.float32)
    image.pixels.foreach_get(px)
    return px.reshape(image.size[1], image.size[0], 4)


def lightmap_pixels():
    return {name: pixels(bpy.data.images[name + "_lightmap"]).tobytes()
            for name in scenes.CORNELL_OBJECTS if name + "_lightmap" in bpy.data.images}


def shows_live(live_preview):
    """Every Cornell material's lightmap node shows its live image and its preview output is active."""
    from photonlm_blender.export import materials
    for name in scenes.CORNELL_OBJECTS:
        tree = bpy.data.materials["mat_" + name].node_tree
        tex = next((n for n in tree.nodes if n.get(materials.TAG) == "image"), None)
        out = next((n for n in tree.nodes if n.get(materials.TAG) == "output"), None)
        if tex is None or tex.image is None or tex.image.name != live_preview.IMAGE_PREFIX + name:
            return False
        if out is None or not out.is_active_output:
            return False
    return True


def child():
    try:
        scenes.setup_paths()
        from photonlm_blender.bake import job as bake  # noqa: F401
        from photonlm_blender.preview import live as live_preview
        from photonlm_blender.operators import bake as operators
    except Exception as e:  # noqa: BLE001 -- report to the parent and quit, never hang
        scenes.write_windowed_result({"error": "child set-up failed: %s" % e})
        return
    _child(bake, live_preview, operators)


def _child(bake, live_preview, operators):
    scenes.clear_scene()
    scenes.cornell_box()
    scene = bpy.context.scene
    s = scene.photonlm
    s.seed = 5
    s.target_error = 0.0  # exactly Max Photons
    s.live_preview = INTERVAL
    res = {}
    state = {"phase": "fresh_start"}

    def invoke():
        with bpy.context.temp_override(**scenes.view3d_override()):
            return sorted(bpy.ops.photonlm.bake('INVOKE_DEFAULT'))

    def finish():
        scenes.write_windowed_result(res)

    def tick():
        try:
            return step()
        except Exception as e:  # noqa: BLE001 -- report to the parent and quit, never hang
            import traceback
            traceback.print_exc()
            res["error"] = "child failed in phase %s: %r" % (state["phase"], e)
            finish()
            return None

    def cancel_after_refresh(prefix):
        """Watch a long bake; cancel it after its first refresh. True once it has ended."""
        op = operators._running
        if op is not None:
            if "t_cancel" not in state and op._live is not None and op._live.refreshes >= 1:
                res[prefix + "_wired_live"] = shows_live(live_preview)
                res[prefix + "_refreshed"] = True
                op._cancel.set()  # what the Esc key does
                state["t_cancel"] = time.perf_counter()
            if time.perf_counter() - state["t_start"] > 200:
                op._cancel.set()
            return False
        state.pop("t_cancel", None)
        res.setdefault(prefix + "_refreshed", False)
        return True

    def step():
        phase = state["phase"]
        if phase == "fresh_start":
            # Previews are copied only while a viewport shows materials; Eevee drawing them in
            # software (Xvfb) would starve the window's timers, so the viewport stays in Solid and
            # the add-on is told it is watched, after checking that it looks at the shading.
            shading = scenes.view3d_override()["area"].spaces.active.shading
            with bpy.context.temp_override(**scenes.view3d_override()):
                shading.type = 'SOLID'
                res["watched_solid"] = live_preview.watched(bpy.context)
                shading.type = 'MATERIAL'
                res["watched_material"] = live_preview.watched(bpy.context)
                shading.type = 'SOLID'
            live_preview.watched = lambda context: True
            state["fp"], state["names"] = fingerprint(), data_names()
            s.photons = 2_000_000_000
            assert invoke() == ['RUNNING_MODAL']
            state["t_start"] = time.perf_counter()
            state["phase"] = "fresh"
            return 0.05
        if phase == "fresh":
            if not cancel_after_refresh("fresh"):
                return 0.05
            fp = fingerprint()
            res["fresh_restored"] = fp == state["fp"]
            res["fresh_diff"] = diff(state["fp"], fp)
            res["fresh_no_new_data"] = data_names() == state["names"]
            res["fresh_new"] = str(data_names()) if not res["fresh_no_new_data"] else ""
            # 2. the reference, previews off (synchronous), then the live bake
            s.photons = PHOTONS
            s.live_preview = 0.0
            assert bpy.ops.photonlm.bake() == {'FINISHED'}
            state["reference"] = lightmap_pixels()
            s.live_preview = INTERVAL
            res["refreshes"], state["seen"] = [], 0
            res["pixels_changed"], res["all_finite"], res["wired_live"] = False, True, True
            state["last_px"] = None
            assert invoke() == ['RUNNING_MODAL']
            state["phase"] = "live"
            return 0.05
        if phase == "live":
            op = operators._running
            if op is not None:
                live = op._live
                if live is not None and live.refreshes > state["seen"]:
                    state["seen"] = live.refreshes
                    means, px_all = {}, []
                    for name in WATCHED:
                        px = pixels(bpy.data.images[live_preview.IMAGE_PREFIX + name])[..., :3]
                        res["all_finite"] &= bool(np.all(np.isfinite(px)) and px.min() >= 0.0)
                        means[name] = float(px.mean())
                        px_all.append(px.tobytes())
                    if state["last_px"] is not None and px_all != state["last_px"]:
                        res["pixels_changed"] = True
                    state["last_px"] = px_all
                    res["refreshes"].append((live.photons, means))
                    res["wired_live"] &= shows_live(live_preview)
                return 0.02
            final = lightmap_pixels()
            res["final_equal"] = (sorted(final) == sorted(scenes.CORNELL_OBJECTS)
                                  and final == state["reference"])
            res["final_means"] = {name: float(pixels(bpy.data.images[name + "_lightmap"])[..., :3].mean())
                                  for name in WATCHED}
            res["live_images_gone"] = not any(i.name.startswith(live_preview.IMAGE_PREFIX)
                                              for i in bpy.data.images)
            res["final_wired"] = all(
                any(getattr(n, "image", None) is not None and n.image.name == name + "_lightmap"
                    for n in bpy.data.materials["mat_" + name].node_tree.nodes)
                for name in scenes.CORNELL_OBJECTS)
            # 3. cancel over these lightmaps
            state["fp"], state["names"], state["px"] = fingerprint(), data_names(), lightmap_pixels()
            s.photons = 2_000_000_000
            assert invoke() == ['RUNNING_MODAL']
            state["t_start"] = time.perf_counter()
            state["phase"] = "second"
            return 0.05
        if phase == "second":
            if not cancel_after_refresh("second"):
                return 0.05
            fp = fingerprint()
            res["second_restored"] = fp == state["fp"]
            res["second_diff"] = diff(state["fp"], fp)
            res["second_pixels"] = lightmap_pixels() == state["px"]
            res["second_no_new_data"] = data_names() == state["names"]
            res["second_new"] = str(data_names()) if not res["second_no_new_data"] else ""
            finish()
            return None
        return None

    bpy.app.timers.register(tick, first_interval=1.0)
    print("CHILD started", flush=True)


if scenes.is_windowed_child():
    child()
else:
    parent()
