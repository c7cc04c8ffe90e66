"""The interactive path: bpy.ops.photonlm.bake('INVOKE_DEFAULT') runs as a modal operator with a
worker thread, a progress bar and Esc to cancel. That needs a window, which `blender -b` has
not, so this script (started by CTest with -b) re-runs itself in a windowed Blender under
xvfb-run and checks what the child reports. Without xvfb-run it prints SKIP and passes.

In the window: a modal bake of the Cornell box must finish with the lightmaps and statistics
while Blender keeps processing events (timer ticks during the bake); a second modal bake
cancelled after one second (the Esc handler's flag) must stop promptly and leave the images,
files and statistics of the first bake untouched.
"""
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402



def parent():
    checks = scenes.Checks("modal_operator")
    r = scenes.run_windowed(checks, "modal_operator", __file__, timeout=300)
    if r is None:
        return
    checks.check(r["invoke"] == ["RUNNING_MODAL"], "invoke starts a modal operator (%s)" % r["invoke"])
    checks.check(r["ticks"] >= 3, "Blender kept running during the bake (%d timer ticks)" % r["ticks"])
    checks.check(r["objects"] == sorted(scenes.CORNELL_OBJECTS), "modal bake produced the 7 lightmaps")
    checks.check(r["images_match"], "modal bake: images equal the engine's lightmaps")
    checks.check(r["stats_time"].endswith(" s"), "statistics updated (%s)" % r["stats_time"])
    checks.check(r["invoke2"] == ["RUNNING_MODAL"], "second modal bake started")
    # The 2e9-photon bake would run for minutes; a loose bound, as loaded machines stall threads.
    checks.check(r["cancel_seconds"] < 30.0, "cancel stops the bake long before its end (%.2f s after the request)"
                 % r["cancel_seconds"])
    checks.check(r["unchanged_after_cancel"], "cancel leaves images, files and statistics untouched")
    checks.finish()


def child():
    try:
        scenes.setup_paths()
        from photonlm_blender.operators import bake as operators
        from photonlm_blender.writeback import record
    except Exception as e:  # noqa: BLE001 -- report to the parent and quit, never hang
        scenes.write_windowed_result({"error": "child set-up failed: %s" % e})
        return
    _child(record, operators)


def _child(record, operators):
    scenes.clear_scene()
    scenes.cornell_box()
    scene = bpy.context.scene
    scene.photonlm.photons = 10_000_000
    scene.photonlm.target_error = 0.0  # exactly that many photons: a bake long enough to watch
    res = {"ticks": 0}
    state = {"phase": "start"}

    def snapshot():
        imgs = {}
        for name, o in record.last().get("objects", {}).items():
            img = bpy.data.images[name + "_lightmap"]
            px = np.empty(img.size[0] * img.size[1] * 4, np.float32)
            img.pixels.foreach_get(px)
            imgs[name] = (px.tobytes(), os.path.getmtime(o["path"]))
        return imgs, scene.photonlm.last_photons, scene.photonlm.last_time

    def finish():
        scenes.write_windowed_result(res)

    def tick():
        try:
            return step()
        except Exception as e:  # noqa: BLE001 -- report to the parent and quit, never hang
            res["error"] = "child failed: %r" % e
            finish()
            return None

    def step():
        phase = state["phase"]
        if phase == "start":
            with bpy.context.temp_override(**scenes.view3d_override()):
                res["invoke"] = sorted(bpy.ops.photonlm.bake('INVOKE_DEFAULT'))
            state["phase"] = "first"
            return 0.1
        if phase == "first":
            if operators._running is not None:
                res["ticks"] += 1
                return 0.1
            res["objects"] = sorted(record.last().get("objects", {}))
            ok = True
            for name, o in record.last().get("objects", {}).items():
                img = bpy.data.images[name + "_lightmap"]
                px = np.empty(img.size[0] * img.size[1] * 4, np.float32)
                img.pixels.foreach_get(px)
                ok &= np.array_equal(px.reshape(img.size[1], img.size[0], 4)[..., :3], o["rgb"])
            res["images_match"] = bool(ok)
            res["stats_time"] = scene.photonlm.last_time
            state["before"] = snapshot()
            scene.photonlm.photons = 2_000_000_000
            scene.photonlm.target_error = 0.0  # exactly that many photons: long enough to cancel
            with bpy.context.temp_override(**scenes.view3d_override()):
                res["invoke2"] = sorted(bpy.ops.photonlm.bake('INVOKE_DEFAULT'))
            state["phase"] = "second"
            state["t_start"] = time.perf_counter()
            return 0.1
        if phase == "second":
            op = operators._running
            if op is not None and "t_cancel" not in state and time.perf_counter() - state["t_start"] > 1.0:
                op._cancel.set()  # what the Esc key does
                state["t_cancel"] = time.perf_counter()
            if op is not None:
                if time.perf_counter() - state["t_start"] > 120:
                    res["cancel_seconds"] = 1e9
                    res["unchanged_after_cancel"] = False
                    finish()
                    return None
                return 0.05
            res["cancel_seconds"] = time.perf_counter() - state.get("t_cancel", state["t_start"])
            res["unchanged_after_cancel"] = snapshot() == state["before"]
            finish()
            return None
        return None

    bpy.app.timers.register(tick, first_interval=1.0)
    print("CHILD started", flush=True)


if scenes.is_windowed_child():
    child()
else:
    parent()
