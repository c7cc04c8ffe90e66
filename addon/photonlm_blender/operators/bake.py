"""Operators: bake (modal with a progress bar when invoked, synchronous when executed by a
script or `blender -b`) and removing the preview nodes."""
import threading
import time

import bpy

from ..bake.job import BakeError, BakeJob
from ..preview import live as live_preview
from ..writeback import wiring

_running = None  # the operator instance of the bake in progress (one at a time)


def running():
    """The operator instance of the bake in progress, or None."""
    return _running


def progress_text(fraction, stage, seconds):
    """'tracing photons - 12 s left': the stage and a time estimate from the fraction done so far
    (the engine's fraction covers the whole bake and never goes back)."""
    if fraction > 0.02 and seconds > 1.0:
        return "%s - %s left" % (stage, _duration(seconds * (1.0 - fraction) / fraction))
    return "%s - %s" % (stage, _duration(seconds))


def _duration(seconds):
    seconds = int(round(seconds))
    if seconds >= 3600:
        return "%d h %02d min" % (seconds // 3600, seconds % 3600 // 60)
    if seconds >= 60:
        return "%d min %02d s" % (seconds // 60, seconds % 60)
    return "%d s" % seconds


def report_all(op, reports):
    """Send a job's reports (export.scene.Reports, or None before there were any) to the operator (the info
    editor / console)."""
    for level, text in (reports.items if reports is not None else ()):
        op.report({level if level in ('INFO', 'WARNING', 'ERROR') else 'INFO'}, text)


class PHOTONLM_OT_bake(bpy.types.Operator):
    """Bake photon lightmaps (global illumination) for the visible mesh objects"""
    bl_idname = "photonlm.bake"
    bl_label = "Bake Lightmaps"
    bl_options = {'REGISTER', 'UNDO'}

    selected_only: bpy.props.BoolProperty(
        name="Selected Only", default=False, options={'SKIP_SAVE'},
        description="Bake only the selected objects' lightmaps; the other visible objects still block and "
                    "reflect light, and their lightmaps stay as they are")

    @classmethod
    def description(cls, context, properties):
        if properties.selected_only:
            return ("Bake the lightmaps of the selected objects only; the other visible objects still block and "
                    "reflect light, and their lightmaps stay as they are")
        return "Bake photon lightmaps (global illumination) for the visible mesh objects"

    @classmethod
    def poll(cls, context):
        if _running is not None:
            cls.poll_message_set("A lightmap bake is already running")
            return False
        if context.mode != 'OBJECT':
            cls.poll_message_set("Switch to Object Mode to bake lightmaps")
            return False
        return True

    def _prepare(self, context):
        try:
            return BakeJob(context, self.selected_only)
        except (BakeError, RuntimeError) as e:
            self.report({'ERROR'}, str(e))
        except Exception as e:  # noqa: BLE001 -- never take Blender down
            self.report({'ERROR'}, "PhotonLM: could not export the scene: %s" % e)
        return None

    def _conclude(self, context, job):
        """Finish or abort a job whose run() has returned; returns the operator result."""
        if job.cancelled or job.error:
            job.abort(context)
            report_all(self, job.reports)
            if job.error:
                self.report({'ERROR'}, job.error)
            else:
                self.report({'WARNING'}, "Lightmap bake cancelled")
            return {'CANCELLED'}
        try:
            last = job.finish(context)
        except Exception as e:  # noqa: BLE001
            job.abort(context)
            report_all(self, job.reports)
            self.report({'ERROR'}, "PhotonLM: could not store the lightmaps: %s" % (getattr(e, "message", None) or e))
            return {'CANCELLED'}
        report_all(self, job.reports)
        s = last["stats"]
        # Above twice the target (or twice the error): said only for an error above rounding (a bake
        # whose light has no noise, e.g. a uniform sky on an open wall, reads 1e-15).
        above = (" (%.1f %% of the texels above %.3g %%)" % (100.0 * s["error_above"], 200.0 * s["error_target"])
                 if s["error_target"] > 1e-9 else "")
        self.report({'INFO'}, "Baked %d lightmaps: %s photons in %.2f s (%.2f M photons/s), error %.2f %%%s, "
                    "%d warnings"
                    % (len(last["objects"]), "{:,}".format(int(s["photons_emitted"])), s["seconds_total"],
                       s["photons_per_second"] / 1e6, 100.0 * s["error_estimate"], above, s["warning_count"]))
        # Last, so that the status bar shows them: the bake came close to the memory free, or much
        # of the lightmap is noisy.
        for text in job.notices:
            print("PhotonLM warning: %s" % text)
            self.report({'WARNING'}, text)
        return {'FINISHED'}

    def execute(self, context):
        job = self._prepare(context)
        if job is None:
            return {'CANCELLED'}
        job.run(progress=None)
        return self._conclude(context, job)

    # ---- modal ---------------------------------------------------------------------------
    def invoke(self, context, event):
        global _running
        if context.window_manager is None or not context.window_manager.windows:
            return self.execute(context)
        job = self._prepare(context)
        if job is None:
            return {'CANCELLED'}
        self._job = job
        self._fraction = 0.0
        self._stage = "starting"
        self._cancel = threading.Event()
        interval = float(context.scene.photonlm.live_preview)
        self._live = live_preview.LivePreview(job, interval) if interval > 0.0 else None
        if self._live is not None:
            self._live.watched = live_preview.watched(context)
        live = (self._live.take, interval) if self._live else (None, 0.0)
        self._thread = threading.Thread(target=job.run, args=(self._progress,) + live, name="photonlm-bake",
                                        daemon=True)
        self._t0 = time.perf_counter()
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.progress_begin(0, 1000)
        wm.modal_handler_add(self)
        _running = self
        self._thread.start()
        return {'RUNNING_MODAL'}

    def _progress(self, fraction, stage):
        """Called by the engine on the worker thread: store, never touch bpy."""
        self._fraction = fraction
        self._stage = stage
        return not self._cancel.is_set()

    def modal(self, context, event):
        if event.type == 'ESC' and event.value == 'PRESS':
            self._cancel.set()
            return {'RUNNING_MODAL'}
        if event.type != 'TIMER':
            return {'PASS_THROUGH'}
        wm = context.window_manager
        if self._thread.is_alive():
            if self._live is not None and not self._cancel.is_set():
                self._live.apply(context)
            wm.progress_update(int(1000 * min(max(self._fraction, 0.0), 1.0)))
            text = "PhotonLM: %d%%, %s%s" % (
                round(100 * self._fraction), progress_text(self._fraction, self._stage, time.perf_counter() - self._t0),
                " - cancelling" if self._cancel.is_set() else " - Esc to cancel")
            if context.workspace is not None:
                context.workspace.status_text_set(text)
            for area in context.screen.areas if context.screen else ():
                if area.type == 'PROPERTIES':
                    area.tag_redraw()  # the panel's progress bar
            return {'RUNNING_MODAL'}
        return self._end(context)

    def _stop_ui(self, context):
        """Wait for the worker, then remove the timer, progress bar and status text."""
        global _running
        self._thread.join()
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        _running = None

    def _end(self, context):
        self._stop_ui(context)
        result = self._conclude(context, self._job)
        if self._live is not None:
            self._live.end('FINISHED' in result)
        for area in context.screen.areas if context.screen else ():
            area.tag_redraw()
        return result

    def cancel(self, context):
        # Blender ends the modal operator (file load, quit): stop the engine and clean up.
        self._cancel.set()
        self._stop_ui(context)
        self._job.abort(context)
        if self._live is not None:
            self._live.end(False)


class PHOTONLM_OT_remove_preview(bpy.types.Operator):
    """Remove the PhotonLM preview nodes (lightmaps and error heat map) from all materials and the
    heat-map images (the lightmap images and all files are kept)"""
    bl_idname = "photonlm.remove_preview"
    bl_label = "Remove Preview Nodes"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        n = sum(1 for mat in bpy.data.materials if wiring.remove_wiring(mat))
        k = wiring.remove_error_images()
        self.report({'INFO'}, "Removed the lightmap preview from %d materials (and %d heat-map images)" % (n, k))
        return {'FINISHED'}


_CLASSES = (PHOTONLM_OT_bake, PHOTONLM_OT_remove_preview)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
