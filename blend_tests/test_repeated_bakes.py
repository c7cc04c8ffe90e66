"""Repeated bakes and add-on reloads do not leak: 20 bakes of the Cornell box in one Blender,
with the add-on disabled and re-enabled halfway, keep the process's resident memory flat.

Expected: after a warm-up of 3 bakes, resident memory (VmRSS) grows by less than 40 MB over
the next 17 bakes (one bake's lightmaps are ~1 MB; a leak of the engine's texel arrays,
Embree scene or result handles would grow by several MB per bake). Every bake finishes and
the images keep their names (no `_lightmap.001` duplicates).
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402


def rss_mb():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return 0.0


def main():
    checks = scenes.Checks("repeated_bakes")
    addon = scenes.setup_paths()
    scenes.clear_scene()
    scenes.cornell_box(resolution=32)
    bpy.context.scene.photonlm.output_dir = scenes.out_dir("repeated")
    rss = []
    ok = True
    for i in range(20):
        if i == 10:  # disable and re-enable the add-on between bakes
            addon.unregister()
            addon.register()
            bpy.context.scene.photonlm.output_dir = scenes.out_dir("repeated")
        try:
            scenes.photonlm_bake(300_000, 64, seed=i, target_error=0.0)
        except Exception as e:  # noqa: BLE001
            ok = False
            print("bake %d failed: %s" % (i, e))
        rss.append(rss_mb())
        print("bake %2d: RSS %.1f MB" % (i, rss[-1]), flush=True)
    checks.check(ok, "20 bakes finished (add-on re-registered after 10)")
    growth = rss[-1] - rss[2]
    checks.check(growth < 40.0, "resident memory after warm-up grew %.1f MB over 17 bakes (%.1f -> %.1f MB), "
                 "limit 40 MB" % (growth, rss[2], rss[-1]))
    dupes = [im.name for im in bpy.data.images if ".0" in im.name]
    checks.check(not dupes, "no duplicate images (%s)" % dupes)
    checks.finish()


main()
