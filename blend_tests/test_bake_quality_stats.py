"""The quality figures of a bake: stored on the scene, in record.last() and shown in the panel.

A noisy bake (a 256 x 256 floor and a 128 x 128 box under a sun and a sky, stopped after
200,000 photons with 4 direct samples, target 2 %) and a quiet one (the floor alone at 32 x 32,
target 2 % reached):
- scene['photonlm_last_bake'] holds error_estimate, error_median, error_p95, error_above,
  error_target, memory_estimate and the noisiest object, equal to the engine's statistics;
- the add-on's own count over the lightmaps (texels whose error / value is above twice the
  target, per object) adds up to the engine's error_above;
- the Last Bake box (drawn into a recording layout) shows the RMS error with its target, the
  share above twice the target, the 95th percentile, the noisiest object (the one with the largest
  relative RMS error, the engine's, with that error) and, when more than 10 % is above, a one-line
  hint; the quiet bake shows no hint, and its one object within the target as the noisiest;
- the noisy bake's report ends with a warning naming the noisiest object.
"""
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402


class Layout:
    """Stands in for bpy.types.UILayout: records the labels and properties a panel draws."""

    def __init__(self, lines):
        self.lines = lines

    def __getattr__(self, name):  # use_property_split, scale_y, alignment, enabled... are set only
        raise AttributeError(name)

    def __setattr__(self, name, value):
        object.__setattr__(self, name, value)

    def _child(self, *args, **kwargs):
        return Layout(self.lines)

    column = row = box = split = column_flow = grid_flow = _child

    def label(self, text="", icon='NONE', **kwargs):
        self.lines.append(("label", text, icon))

    def prop(self, data, name, text=None, **kwargs):
        self.lines.append(("prop", name, text))

    def operator(self, idname, text=None, **kwargs):
        self.lines.append(("operator", idname, text))

    def operator_menu_enum(self, idname, prop, text=None, **kwargs):
        self.lines.append(("operator", idname, text))

    def separator(self, **kwargs):
        pass


def last_bake_box(context):
    """The Last Bake box as (label, value) rows and the other labels after its title."""
    from photonlm_blender.ui import panel
    lines = []

    class Panel:
        layout = Layout(lines)
    panel.PHOTONLM_PT_last_bake.draw(Panel, context)
    box = [l for l in lines if l[0] == "label"]
    rows, rest = {}, []
    i = 0
    while i < len(box):  # a row is a label pair from one split (the hint stands alone, with an icon)
        if box[i][2] == 'NONE' and i + 1 < len(box) and box[i + 1][2] == 'NONE':
            rows[box[i][1]] = box[i + 1][1]
            i += 2
        else:
            rest.append(box[i][1])
            i += 1
    return rows, rest


def build(resolution_floor, resolution_box=None):
    scenes.clear_scene()
    scenes.plane("floor", scenes.diffuse_material("floor_mat", (0.7, 0.7, 0.7)), size=4.0,
                 resolution=resolution_floor)
    if resolution_box:
        texel = 3.4 / resolution_box  # the five faces fit the map
        scenes.quads_object("box", scenes.box_quads((0.3, 0.2), 0.4, 0.4, 0.8, 0.3, texel, resolution_box),
                            scenes.diffuse_material("box_mat", (0.6, 0.4, 0.3)), resolution_box)
    scenes.add_light("sun", 'SUN', (0, 0, 5), rotation=(0.5, 0.3, 0), energy=3.0)
    scenes.set_world_color((0.3, 0.4, 0.5), 0.5)


def main():
    t_start = time.perf_counter()
    scenes.setup_paths()
    from photonlm_blender.writeback import record
    checks = scenes.Checks("bake_quality_stats")
    context = bpy.context

    # -- a noisy bake --------------------------------------------------------------------------------------------
    build(256, 128)
    last = scenes.photonlm_bake(200_000, 8, seed=2, target_error=0.02, direct_samples=4)
    s = last["stats"]
    stored = dict(context.scene[record.STATS_KEY])
    print("bake_quality_stats: noisy bake %.1f s: error %.2f %%, median %.1f %%, p95 %.1f %%, above %.1f %%"
          % (last["wall_seconds"], 100 * s["error_estimate"], 100 * s["error_median"], 100 * s["error_p95"],
             100 * s["error_above"]))
    keys = ("error_estimate", "error_median", "error_p95", "error_above", "memory_estimate")
    checks.check(all(k in stored and abs(float(stored[k]) - float(s[k])) <= 1e-9 * max(1.0, abs(float(s[k])))
                     for k in keys), "the scene's statistics hold the engine's %s" % ", ".join(keys))
    checks.check(abs(stored["error_target"] - 0.02) < 1e-6 and abs(stored["target_error"] - 0.02) < 1e-6,
                 "and the target (%.4f)" % stored["error_target"])
    checks.check(s["memory_estimate"] > 256 * 256 * 240, "memory estimate %.0f MB" % (s["memory_estimate"] / 1e6))
    above = sum(o["texels_above"] for o in last["objects"].values())
    texels = sum(o["texels"] for o in last["objects"].values())
    checks.check(abs(above / texels - s["error_above"]) < 2e-3,
                 "the lightmaps' texels above twice the target add up to the engine's share (%.4f vs %.4f)"
                 % (above / texels, s["error_above"]))
    checks.check(s["error_above"] > record.NOISY_SHARE, "the bake is noisy (%.1f %% above)"
                 % (100 * s["error_above"]))
    # The add-on's rule (bake.noisiest_objects): among the noisy objects, the one holding most noisy texels.
    worst = max((n for n in last["objects"] if last["objects"][n]["error_above"] > record.NOISY_SHARE),
                key=lambda n: last["objects"][n]["texels_above"])
    checks.check(stored["noisiest"] == worst == last["noisiest"][0],
                 "the noisy object holding the most noisy texels is stored: %s (%s)" % (stored["noisiest"],
                 ", ".join("%s %.1f %%" % (n, 100 * o["error_above"]) for n, o in last["objects"].items())))
    rows, rest = last_bake_box(context)
    print("bake_quality_stats: Last Bake box %s %s" % (rows, rest))
    checks.check(rows.get("Error") == "%.2f %%  (target 2 %%)" % (100 * s["error_estimate"]),
                 "Last Bake shows the RMS error and its target (%s)" % rows.get("Error"))
    checks.check(rows.get("Above 4 %") == "%.1f %% of texels" % (100 * s["error_above"]),
                 "Last Bake shows the share above twice the target (%s)" % rows.get("Above 4 %"))
    checks.check(rows.get("Percentile 95") == "%.2f %%" % (100 * s["error_p95"]),
                 "Last Bake shows the 95th percentile (%s)" % rows.get("Percentile 95"))
    # The noisiest object: the engine's worst (its mesh id), the baked object with the largest relative RMS error.
    by_error = max(last["objects"], key=lambda n: last["objects"][n]["relative_error"])
    checks.check(stored["worst_object"] == by_error and abs(float(stored["error_worst"]) - s["error_worst"]) < 1e-9
                 and rows.get("Noisiest") == "%s (%.2f %%)" % (by_error, 100 * s["error_worst"]),
                 "and the noisiest object with its error (%s; %s)" % (rows.get("Noisiest"), ", ".join(
                     "%s %.2f %%" % (n, 100 * o["relative_error"]) for n, o in last["objects"].items())))
    checks.check(rest == ["Lower Resolution or add time"], "and a one-line hint (%s)" % rest)
    from photonlm_blender.ui import panel
    from photonlm_blender.writeback import record
    lines = []

    class WarningsPanel:
        layout = Layout(lines)
    panel.PHOTONLM_PT_warnings.draw(WarningsPanel, context)
    shown = " ".join(l[1].strip() for l in lines if l[0] == "label")
    checks.check(panel.PHOTONLM_PT_warnings.poll(context) and "above twice the target error" in shown
                 and "'%s'" % worst in shown and all(len(l[1]) <= 60 for l in lines if l[0] == "label"),
                 "the Warnings sub-panel lists the bake's warnings in lines that fit the panel: %s" % shown[:120])
    checks.check(all(len(label) <= 13 for label in rows) and all(len(v) <= 22 for v in rows.values())
                 and all(len(t) <= 30 for t in rest), "labels short enough for the default panel width")
    # Where the time went: the export's stages add up to the export, the engine's are the engine's own.
    parts = [k for k in stored if k.startswith("seconds_export_")]
    checks.check({"seconds_export_uv", "seconds_export_meshes", "seconds_export_materials", "seconds_export_world",
                  "seconds_export_depsgraph", "seconds_export_checks"} <= set(parts)
                 and all(float(stored[k]) >= 0.0 for k in parts)
                 and abs(sum(float(stored[k]) for k in parts) - float(stored["seconds_export"])) < 1e-6,
                 "the export's stages (%s) add up to its %.3f s"
                 % (", ".join("%s %.3f" % (k[15:], stored[k]) for k in sorted(parts)), stored["seconds_export"]))
    checks.check(all(abs(float(stored[k]) - float(s[k])) <= 1e-9 * max(1.0, float(s[k]))
                     for k in ("seconds_setup", "seconds_trace", "seconds_direct", "seconds_total"))
                 and 0.0 < float(stored["seconds_writeback"]) < last["wall_seconds"],
                 "the engine's stages and the write-back (%.3f s) are stored" % stored["seconds_writeback"])
    checks.check(int(stored["triangles"]) == 2 + 10, "the triangles traced are stored (%d)" % stored["triangles"])
    lines = []

    class TimesPanel:
        layout = Layout(lines)
    panel.PHOTONLM_PT_last_times.draw(TimesPanel, context)
    shown = [l[1].strip() for l in lines if l[0] == "label"]
    checks.check(panel.PHOTONLM_PT_last_times.poll(context) and "Export" in shown and "Write-back" in shown
                 and "%.2f s" % stored["seconds_trace"] in shown and "Meshes" in shown,
                 "the Times sub-panel lists the stages: %s" % " ".join(shown)[:160])
    checks.check(last["reports"][-1][0] == 'WARNING' and "'%s'" % worst in last["reports"][-1][1]
                 and "above twice the target error" in last["reports"][-1][1],
                 "the last report says how much is noisy and names the noisiest: %s" % last["reports"][-1][1])

    # -- a quiet bake ------------------------------------------------------------------------------------------------------
    build(32)
    last = scenes.photonlm_bake(8_000_000, 8, seed=2, target_error=0.02)
    s = last["stats"]
    rows, rest = last_bake_box(context)
    print("bake_quality_stats: quiet bake %.1f s: error %.2f %%, above %.1f %%; box %s %s"
          % (last["wall_seconds"], 100 * s["error_estimate"], 100 * s["error_above"], rows, rest))
    checks.check(s["error_above"] <= record.NOISY_SHARE, "the quiet bake is quiet (%.1f %% above)"
                 % (100 * s["error_above"]))
    checks.check("Above 4 %" in rows and "Percentile 95" in rows, "Last Bake still shows the share and p95")
    checks.check(rest == [] and rows.get("Noisiest", "").startswith("floor (") and s["error_worst"] <= 0.02,
                 "no hint, and the floor within the target as the noisiest object (%s %s)" % (rows.get("Noisiest"), rest))
    checks.check(not any("above twice" in t for _, t in last["reports"]), "no noisy-lightmap warning")
    print("bake_quality_stats: %.1f s" % (time.perf_counter() - t_start))
    checks.finish()


try:
    main()
except Exception:
    import traceback
    traceback.print_exc()
    sys.exit(1)
