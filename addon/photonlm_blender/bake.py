"""One bake, in three steps so that the long middle step can run on a worker thread.

    job = BakeJob(context)           # main thread: create lightmap UVs, export the scene
    job.run(progress)                # any thread: photonlm.Scene.bake (numpy + bridge only)
    job.finish(context)              # main thread: write EXRs, load images, wire materials
    job.abort(context)               # main thread, instead of finish: undo what prepare did

Nothing outside the job changes before finish(): a cancelled or failed bake leaves the
earlier lightmap images and files as they were (what it did to lightmap UV maps is undone).

The last finished bake is described by LAST (a dict: stats, warnings and per object the
mesh id, image name, EXR path and the coverage mask), for scripts and tests.
"""
import os
import tempfile
import time

import bpy

from . import bridge, export, lsystem, materials, properties, uvmaps

LAST = {}


class BakeError(Exception):
    """A bake could not start or finish; the message is for the user."""


def output_directory(scene):
    """The absolute output folder for lightmaps, created if needed.

    A relative (//) path is relative to the .blend file; for an unsaved file it is relative to
    $PHOTONLM_TEST_OUT if set, else to <temp>/photonlm.
    """
    path = scene.photonlm.output_dir or "//lightmaps/"
    if path.startswith("//") and not bpy.data.is_saved:
        base = os.environ.get("PHOTONLM_TEST_OUT") or os.path.join(tempfile.gettempdir(), "photonlm")
        path = os.path.join(base, path[2:])
    else:
        path = bpy.path.abspath(path)
    path = os.path.normpath(path)
    os.makedirs(path, exist_ok=True)
    return path


def bake_settings(scene):
    """The scene's PhotonLM settings as arguments of photonlm.Scene.bake (also written into
    exported scene files, so that `photonlm bake` bakes what the add-on would)."""
    settings = scene.photonlm
    return dict(photons=int(settings.photons), max_bounces=int(settings.max_bounces),
                seed=int(settings.seed), target_error=float(settings.target_error),
                time_budget=float(settings.time_budget), direct_samples=int(settings.direct_samples),
                texel_value=settings.texel_value)


class BakeJob:
    def __init__(self, context):
        self.reports = export.Reports()
        self.photonlm = bridge.get()           # RuntimeError with a readable message if missing
        self.settings = bake_settings(context.scene)
        self.scene_name = context.scene.name
        self.result = None
        self.export = None
        self.error = None
        self.cancelled = False
        self.created_uvs = []
        objects = export.lightmap_objects(context)
        if not objects and not any(lsystem.is_lsystem(o) for o in context.view_layer.objects):
            raise BakeError("nothing to bake: no visible mesh object with 'Bake Lightmap' enabled")
        t0 = time.perf_counter()
        try:
            self.created_uvs = export.ensure_lightmap_uvs(context, objects, self.reports)
            self.export = export.export_scene(context, self.photonlm, self.reports)
        except Exception:
            self.abort(context)
            raise
        self.seconds_export = time.perf_counter() - t0
        if not self.export.baked and not self.export.lsystems:
            self.abort(context)
            raise BakeError("nothing to bake: every object was skipped (see the reports)")

    # -- worker side: no bpy below this line until finish() ---------------------------------
    def run(self, progress=None):
        """Run the engine. Sets .result, or .cancelled / .error. Never raises."""
        try:
            self.result = self.export.scene.bake(progress=progress, **self.settings)
        except self.photonlm.BakeCancelled:
            self.cancelled = True
        except Exception as e:  # noqa: BLE001 -- reported to the user by the operator
            self.error = "bake failed: %s" % (getattr(e, "message", None) or e)
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
        """Write the EXRs, (re)load the images, wire the materials, store the statistics."""
        result = self.result
        try:
            stats = result.stats
            warnings = result.warnings
            for w in uvmaps.summarise_warnings(warnings):
                self.reports.warning("engine: " + w)
            out_dir = output_directory(context.scene)
            scene = context.scene
            per_object = {}
            used_files = set()
            images = {}
            for b in self.export.baked:
                base = export.safe_file_name(b.object_name)
                fname = base + "_lightmap.exr"
                k = 1
                while fname.lower() in used_files:
                    k += 1
                    fname = "%s_%d_lightmap.exr" % (base, k)
                used_files.add(fname.lower())
                path = os.path.join(out_dir, fname)
                result.write_exr(b.mesh_id, path)
                lm = result.lightmap(b.mesh_id)
                image = load_image(b.object_name + "_lightmap", path)
                images[b.object_name] = image
                small = b.width * b.height <= 1024 * 1024
                per_object[b.object_name] = dict(mesh_id=b.mesh_id, image=image.name, path=path,
                                                 size=(b.width, b.height), coverage=lm.coverage,
                                                 rgb=lm.rgb if small else None)
            self._wire(context, images)
            for name, lid in self.export.lsystems:
                obj = bpy.data.objects.get(name)
                if obj is not None:
                    lsystem.store_light(result, lid, obj)
            ol_info = {}
            for group in self.export.ol_groups.values():
                fname = export.safe_file_name(group.name) + "_ol.exr"
                path = os.path.join(out_dir, fname)
                result.write_ol_exr(group.group_id, path)
                st = result.ol_stats(group.group_id)
                ol_info[group.name] = dict(path=path, objects=list(group.objects), reason=group.reason,
                                           resolution=int(st["resolution"]), hits=int(st["hits"]))
                self.reports.info("orientation lightmap '%s' (%d x %d bins, %s): %s"
                                  % (group.name, st["resolution"], st["resolution"],
                                     ", ".join(group.objects), group.reason))
                self._wire_ol(context, group, load_image(group.name + "_ol", path))
        finally:
            result.close()
            self.result = None
        # The photon pass's own rate (the whole bake also holds set-up, the direct pass and writing).
        photons_per_second = stats["photons_emitted"] / max(stats["seconds_trace"], 1e-9) \
            if stats["photons_emitted"] else 0.0
        scene[properties.STATS_KEY] = dict(
            photons_emitted=int(stats["photons_emitted"]), seconds_total=float(stats["seconds_total"]),
            seconds_export=float(self.seconds_export), photons_per_second=float(photons_per_second),
            warning_count=len(warnings), objects=len(self.export.baked),
            photon_hits=int(stats["photon_hits"]), rays_traced=int(stats["rays_traced"]),
            error_estimate=float(stats["error_estimate"]), error_direct=float(stats["error_direct"]),
            error_median=float(stats["error_median"]),
            error_p95=float(stats["error_p95"]), direct_samples=int(stats["direct_samples"]))
        LAST.clear()
        LAST.update(stats=dict(stats, seconds_export=self.seconds_export,
                               photons_per_second=photons_per_second),
                    warnings=list(warnings), objects=per_object, output_dir=out_dir, ols=ol_info,
                    csg_objects=list(self.export.csg_objects),
                    lsystems=[name for name, _ in self.export.lsystems],
                    reports=list(self.reports.items))
        uvmaps.commit(self.created_uvs)  # kept: they belong to the baked lightmaps now
        self.created_uvs = []
        return LAST

    def _wire(self, context, images):
        """Wire each baked object's materials to its lightmap image (first object wins for a
        material shared by several baked objects)."""
        engine = context.scene.render.engine
        owners = {}
        for b in sorted(self.export.baked, key=lambda b: b.object_name):
            for name in b.material_names:
                if name is not None:
                    owners.setdefault(name, [])
                    if b.object_name not in owners[name]:
                        owners[name].append(b.object_name)
            if not any(b.material_names):
                self.reports.warning("object '%s' has no material: lightmap baked, no preview"
                                     % b.object_name)
        for name, objs in owners.items():
            mat = bpy.data.materials.get(name)
            if mat is None:
                continue
            if len(objs) > 1:
                self.reports.warning("material '%s' is shared by %s: its preview shows the lightmap of "
                                     "'%s' only (give each object its own material)"
                                     % (name, ", ".join("'%s'" % o for o in objs), objs[0]))
            for note in materials.wire_material(mat, images[objs[0]], engine):
                self.reports.warning(note)
            materials.set_preview(mat, context.scene.photonlm.preview)


    def _wire_ol(self, context, group, image):
        """Objects of an OL group without a lightmap image of their own (instances, objects without
        'Bake Lightmap'): their materials look the OL up by the world normal (node group
        'PhotonLM OL Lookup'), unless a baked lightmap already owns the material."""
        owned = {n for b in self.export.baked for n in b.material_names if n is not None}
        baked = {b.object_name for b in self.export.baked}
        engine = context.scene.render.engine
        for name in group.objects:
            obj = bpy.data.objects.get(name)
            if obj is None or name in baked:
                continue
            for slot in obj.material_slots:
                mat = slot.material
                if mat is None or mat.name in owned:
                    continue
                for note in materials.wire_material(mat, image, engine, orientation=True):
                    self.reports.warning(note)
                materials.set_preview(mat, context.scene.photonlm.preview)
                owned.add(mat.name)


def load_image(name, path):
    """Load (or reload) the float image `name` from `path`, colour space Non-Color."""
    image = bpy.data.images.get(name)
    if image is not None and image.source == 'FILE' and not image.packed_file:
        image.filepath = path
        image.reload()
    else:
        if image is not None:
            image.name = name + ".old"  # generated or packed: keep it, but free the name
        image = bpy.data.images.load(path, check_existing=False)
        image.name = name
    image.colorspace_settings.name = 'Non-Color'
    if hasattr(image, "use_half_precision"):
        image.use_half_precision = False
    image.alpha_mode = 'NONE'
    return image
