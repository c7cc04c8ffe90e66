"""One bake, in three steps so that the long middle step can run on a worker thread.

    job = BakeJob(context)           # main thread: create lightmap UVs, export the scene
    job.run(progress)                # any thread: photonlm.Scene.bake (numpy + bridge only)
    job.finish(context)              # main thread: the write-back (writeback/apply.py)
    job.abort(context)               # main thread, instead of finish: undo what prepare did

Nothing outside the job changes before finish(): a cancelled or failed bake leaves the
earlier lightmap images and files as they were (what it did to lightmap UV maps is undone).

Before anything changes, the job refuses a scene that nothing lights (no visible light with
power, no emissive material, a black world); the engine refuses it too, and refuses a bake
that would not fit in the memory free (both come back as .error, the scene unchanged). A
directional bake (scene.photonlm.directional) of a scene with light groups, orientation lightmaps,
CSG solids or L-system objects is refused after the export (export/scene.py's
directional_conflict), as the engine would refuse it.

finish() returns the last bake's record (writeback/record.py's last(): the statistics, and per
object the mesh id, image names, EXR paths, the coverage mask and its share of noisy texels).
"""
import time

from .. import bridge, stages
from ..export import lightgroups, lsystem
from ..export import scene as export
from ..uv import uvmaps
from ..writeback import apply, atlas

# Engine statuses that refuse a bake before it begins (the message says why and what to do).
REFUSALS = ("PLM_ERROR_INVALID_SCENE", "PLM_ERROR_OUT_OF_MEMORY")


class BakeError(Exception):
    """A bake could not start or finish; the message is for the user."""


class BakeJob:
    def __init__(self, context, selected_only=False):
        self.reports = export.Reports()
        self.photonlm = bridge.get()           # RuntimeError with a readable message if missing
        self.settings = export.bake_settings(context.scene)
        self.selected_only = selected_only
        self.scene_name = context.scene.name
        self.result = None
        self.export = None
        self.manifest = None
        self.error = None
        self.cancelled = False
        self.created_uvs = []
        self.notices = []  # warnings to show last (after the summary): memory, noisy texels
        self.times = stages.StageTimes()  # seconds per stage, into the statistics (stage_seconds())
        t0, cpu0, process0 = time.perf_counter(), time.thread_time(), time.process_time()
        vl = context.view_layer
        with self.times("export_checks"):
            objects = export.lightmap_objects(context, selected_only)
            if not objects and not any(lsystem.is_lsystem(o) and (not selected_only or o.select_get(view_layer=vl))
                                       for o in vl.objects):
                raise BakeError("nothing to bake: no %s mesh object with 'Bake Lightmap' enabled"
                                % ("selected" if selected_only else "visible"))
            if not export.light_sources(context):
                raise BakeError(export.unlit_scene_message(context))
            try:
                lightgroups.check_names(export.light_group_plan(context))
            except ValueError as e:
                raise BakeError(str(e)) from None
        try:
            with self.times("export_uv"):
                self.created_uvs = uvmaps.ensure_for_scene(context, objects, self.reports)
            self.export = export.export_scene(context, self.photonlm, self.reports, selected_only, self.times)
        except Exception:
            self.abort(context)
            raise
        self.manifest = self.export.manifest  # what the write-back brings back
        self.manifest.target_error = float(self.settings["target_error"])
        self.seconds_export = time.perf_counter() - t0
        self.cpu_seconds_export = time.thread_time() - cpu0  # this thread's: see stages.py
        self.cpu_seconds_export_process = time.process_time() - process0  # all threads (Blender's too)
        if not self.manifest.baked and not self.manifest.lsystems:
            self.abort(context)
            raise BakeError("nothing to bake: every object was skipped (see the reports)")
        refused = export.directional_conflict(self.manifest, self.settings.get("directional", False))
        if refused:
            self.abort(context)
            raise BakeError(refused)
        if atlas.is_atlas(context.scene):
            try:
                atlas.check(context.scene, self.manifest.baked, selected_only)
            except atlas.AtlasError as e:
                self.abort(context)
                raise BakeError(str(e)) from None

    # -- worker side: no bpy below this line until finish() ---------------------------------
    def run(self, progress=None, preview=None, preview_interval=0.0):
        """Run the engine (preview: see preview/live.py). Sets .result, or .cancelled / .error.
        Never raises."""
        try:
            live = {}
            if preview is not None and preview_interval > 0.0:
                live = dict(preview=preview, preview_interval=preview_interval)
            self.result = self.export.scene.bake(progress=progress, **self.settings, **live)
        except self.photonlm.BakeCancelled:
            self.cancelled = True
        except Exception as e:  # noqa: BLE001 -- reported to the user by the operator
            refused = getattr(e, "status", None) in REFUSALS
            self.error = "bake %s: %s" % ("refused" if refused else "failed", getattr(e, "message", None) or e)
        finally:
            self.export.scene.close()
            self.export.texture_files.cleanup()  # the engine copied the images at the bake's start

    # -- main thread again -------------------------------------------------------------------
    def abort(self, context):
        """Undo prepare: undo what it did to the lightmap UV maps; release native objects."""
        uvmaps.undo(self.created_uvs)
        self.created_uvs = []
        if self.export is not None:
            self.export.scene.close()
            self.export.texture_files.cleanup()
        if self.result is not None:
            self.result.close()
            self.result = None

    def finish(self, context):
        """The write-back (writeback/apply.py): EXRs, images, material wiring, statistics. Returns
        the last bake's record."""
        result, self.result = self.result, None
        last = apply.apply(context, self.manifest, result, self.reports, self.stage_seconds(),
                           figures=self.export_cpu_seconds())
        self.notices = last["notices"]
        uvmaps.commit(self.created_uvs)  # kept: they belong to the baked lightmaps now
        self.created_uvs = []
        return last

    def export_cpu_seconds(self):
        """CPU seconds of the export and its stages, for the statistics (scripts and benchmarks)."""
        out = {"cpu_seconds_" + k: float(v) for k, v in self.times.cpu.items()}
        out["cpu_seconds_export_other"] = max(0.0, self.cpu_seconds_export - sum(self.times.cpu.values()))
        out["cpu_seconds_export"] = self.cpu_seconds_export
        out["cpu_seconds_export_process"] = self.cpu_seconds_export_process
        return out

    def stage_seconds(self):
        """Seconds per export stage for the statistics: seconds_export and its parts
        seconds_export_<stage> (checks, uv, cages, depsgraph, meshes, refine, materials, world, other);
        the write-back adds the engine's and its own."""
        out = {"seconds_" + k: float(v) for k, v in self.times.seconds.items()}
        out["seconds_export_other"] = max(0.0, self.seconds_export - self.times.total())
        out["seconds_export"] = float(self.seconds_export)
        return out
