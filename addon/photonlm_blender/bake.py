"""One bake, in three steps so that the long middle step can run on a worker thread.

    job = BakeJob(context)           # main thread: create lightmap UVs, export the scene
    job.run(progress)                # any thread: photonlm.Scene.bake (numpy + bridge only)
    job.finish(context)              # main thread: write EXRs, load images, wire materials
    job.abort(context)               # main thread, instead of finish: undo what prepare did

Nothing outside the job changes before finish(): a cancelled or failed bake leaves the
earlier lightmap images and files as they were (what it did to lightmap UV maps is undone).

Before anything changes, the job refuses a scene that nothing lights (no visible light with
power, no emissive material, a black world); the engine refuses it too, and refuses a bake
that would not fit in the memory free (both come back as .error, the scene unchanged).

The last finished bake is described by LAST (a dict: stats, warnings and per object the
mesh id, image names, EXR paths, the coverage mask and its share of noisy texels), for
scripts and tests. Next to each <object>_lightmap.exr, finish() writes <object>_error.exr:
the texels' relative error (standard error / value; 0 where the texel has no light) in R, G
and B, loaded as the image <object>_error for the heat-map preview.
"""
import atexit
import concurrent.futures
import os
import shutil
import tempfile
import time

import bpy
import numpy as np

from . import atlas, bridge, compat, export, lsystem, materials, properties, stages, uvmaps, world_export

# Heat-map images larger than this per side hold the RMS of blocks of texels.
ERROR_IMAGE_MAX = 2048
# Engine statuses that refuse a bake before it begins (the message says why and what to do).
REFUSALS = ("PLM_ERROR_INVALID_SCENE", "PLM_ERROR_OUT_OF_MEMORY")

LAST = {}


class BakeError(Exception):
    """A bake could not start or finish; the message is for the user."""


_SESSION_FOLDER = []  # this Blender process's own folder for the lightmaps of unsaved files


def _session_folder():
    """A folder no other project or Blender shares, removed when Blender exits."""
    if not _SESSION_FOLDER or not os.path.isdir(_SESSION_FOLDER[0]):
        _SESSION_FOLDER[:] = [tempfile.mkdtemp(prefix="photonlm-unsaved-")]
        atexit.register(shutil.rmtree, _SESSION_FOLDER[0], True)
    return _SESSION_FOLDER[0]


def is_temporary_output(scene):
    """True where the lightmap files are temporary (a relative folder in an unsaved file): the
    images are then packed into the .blend, which is the only place they last."""
    path = scene.photonlm.output_dir or "//lightmaps/"
    return path.startswith("//") and not bpy.data.is_saved and not os.environ.get("PHOTONLM_TEST_OUT")


def output_directory(scene):
    """The absolute output folder for lightmaps, created if needed.

    A relative (//) path is relative to the .blend file; for an unsaved file it is relative to
    $PHOTONLM_TEST_OUT if set, else to a folder of this Blender process's own (removed when it
    exits; the images are packed, see is_temporary_output).
    """
    path = scene.photonlm.output_dir or "//lightmaps/"
    if path.startswith("//") and not bpy.data.is_saved:
        base = os.environ.get("PHOTONLM_TEST_OUT") or _session_folder()
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
    texel_value = settings.texel_value  # 'CYCLES': what this Blender's Cycles bake holds
    if texel_value == 'CYCLES':
        texel_value = compat.cycles_texel_value()
    return dict(photons=int(settings.photons), max_bounces=int(settings.max_bounces),
                seed=int(settings.seed), target_error=float(settings.target_error),
                time_budget=float(settings.time_budget), direct_samples=int(settings.direct_samples),
                texel_value=texel_value, dilation=int(settings.lightmap_margin))


class _Quiet:
    """A Reports stand-in that keeps nothing (for looking at the scene as the export would)."""

    def info(self, text):
        pass

    warning = error = add = info


class _LightRecorder:
    """A photonlm.Scene stand-in for export._add_light: records what would emit."""

    def __init__(self):
        self.emitting = []

    def add_light(self, kind, name="", **settings):
        if kind != 'PORTAL':
            self.emitting.append("light '%s'" % name)


def light_sources(context, limit=1):
    """What would light the scene, as the export sees it: visible lights with power and a colour,
    visible objects with an emissive material, a world that is not black. Stops after `limit`
    finds (0 = all). A list of descriptions; empty when nothing lights the scene."""
    recorder, quiet = _LightRecorder(), _Quiet()
    if world_export.emits(context.scene.world):  # without rendering a sky
        recorder.emitting.append("the world")
    view_layer = context.view_layer
    emissive = {}
    depsgraph = context.evaluated_depsgraph_get()
    for inst in depsgraph.object_instances:
        if limit and len(recorder.emitting) >= limit:
            break
        obj = inst.object
        parent = inst.parent.original if inst.is_instance and inst.parent else obj.original
        if not export.is_renderable(parent, view_layer):
            continue
        if obj.type == 'LIGHT':
            export._add_light(recorder, obj, inst.matrix_world, quiet)
        elif obj.type in export.GEOMETRY_TYPES:
            for slot in obj.material_slots:
                mat = slot.material
                if mat is None:
                    continue
                if mat.name_full not in emissive:
                    emissive[mat.name_full] = max(materials.read_material(mat).emission) > 0.0
                if emissive[mat.name_full]:
                    recorder.emitting.append("material '%s' on '%s'" % (mat.name, obj.original.name))
                    break
    return recorder.emitting


def unlit_scene_message(context):
    """Why nothing lights the scene, naming lights that do not count (hidden, no power, black)."""
    view_layer = context.view_layer
    idle = []
    for obj in context.scene.objects:
        if obj.type != 'LIGHT':
            continue
        light = obj.data
        if light.type == 'AREA' and getattr(getattr(light, "cycles", None), "is_portal", False):
            continue
        if not export.is_renderable(obj, view_layer):
            idle.append("'%s' is hidden" % obj.name)
        elif light.energy <= 0.0:
            idle.append("'%s' has no power" % obj.name)
        elif max(light.color) <= 0.0:
            idle.append("'%s' is black" % obj.name)
    text = ("nothing lights the scene: no visible light with power, no emissive material and a black world, "
            "so every lightmap would be black. Add a light, an emissive material or a world colour")
    if idle:
        text += " (light %s%s)" % (", ".join(idle[:3]), ", ..." if len(idle) > 3 else "")
    return text


class BakeJob:
    def __init__(self, context, selected_only=False):
        self.reports = export.Reports()
        self.photonlm = bridge.get()           # RuntimeError with a readable message if missing
        self.settings = bake_settings(context.scene)
        self.selected_only = selected_only
        self.scene_name = context.scene.name
        self.result = None
        self.export = None
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
            if not light_sources(context):
                raise BakeError(unlit_scene_message(context))
        try:
            with self.times("export_uv"):
                self.created_uvs = export.ensure_lightmap_uvs(context, objects, self.reports)
            self.export = export.export_scene(context, self.photonlm, self.reports, selected_only, self.times)
        except Exception:
            self.abort(context)
            raise
        self.seconds_export = time.perf_counter() - t0
        self.cpu_seconds_export = time.thread_time() - cpu0  # this thread's: see stages.py
        self.cpu_seconds_export_process = time.process_time() - process0  # all threads (Blender's too)
        if not self.export.baked and not self.export.lsystems:
            self.abort(context)
            raise BakeError("nothing to bake: every object was skipped (see the reports)")
        if atlas.is_atlas(context.scene):
            try:
                atlas.check(context.scene, self.export.baked, selected_only)
            except atlas.AtlasError as e:
                self.abort(context)
                raise BakeError(str(e)) from None

    # -- worker side: no bpy below this line until finish() ---------------------------------
    def run(self, progress=None, preview=None, preview_interval=0.0):
        """Run the engine (preview: see live_preview.py). Sets .result, or .cancelled / .error.
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
        """Write the EXRs, (re)load the images, wire the materials, store the statistics."""
        t_finish = time.perf_counter()
        result = self.result
        try:
            stats = result.stats
            warnings = result.warnings
            memory_warnings = [w for w in warnings if is_memory_warning(w)]
            for w in uvmaps.summarise_warnings([w for w in warnings if not is_memory_warning(w)]):
                self.reports.warning("engine: " + w)
            self.notices = ["engine: " + w for w in memory_warnings]
            out_dir = output_directory(context.scene)
            scene = context.scene
            pack = scene.photonlm.pack_lightmaps or is_temporary_output(scene)
            # The heat map's scale and the engine's error_above: twice the target (twice the RMS error
            # without a target).
            target = self.settings["target_error"] if self.settings["target_error"] > 0.0 \
                else float(stats["error_estimate"])
            per_object = {}
            used_files = set()
            images = {}
            error_images = {}
            atlas_mode = atlas.is_atlas(scene)
            atlas_blocks, uv_maps = {}, {}
            # The EXRs are written on threads (the engine's calls release the GIL): a small
            # object's two files cost about 0.8 ms each, which on a small scene is most of the
            # write-back. At most a few objects' writes wait at a time (each holds its heat map's
            # pixels). The images are loaded once all are written.
            writes, paths = [], {}
            workers = os.cpu_count() or 1
            with concurrent.futures.ThreadPoolExecutor(max_workers=workers) as pool:
                for b in self.export.baked:
                    lm = result.lightmap(b.mesh_id)
                    relative = relative_error(lm.rgb, lm.error)
                    path = error_path = None
                    if atlas_mode:  # written into atlas pages below
                        atlas_blocks[b.object_name] = lm
                    else:
                        base = export.safe_file_name(b.object_name)
                        fname = base + "_lightmap.exr"
                        k = 1
                        while fname.lower() in used_files:
                            k += 1
                            fname = "%s_%d_lightmap.exr" % (base, k)
                        used_files.add(fname.lower())
                        path = os.path.join(out_dir, fname)
                        error_path = path[:-len("_lightmap.exr")] + "_error.exr"
                        if len(writes) > 4 * workers:
                            writes[len(writes) - 4 * workers - 1].result()
                        writes.append(pool.submit(result.write_exr, b.mesh_id, path))
                        writes.append(pool.submit(write_error_exr, error_path, error_image_pixels(relative)))
                        paths[b.object_name] = (path, error_path)
                    texels, above = self.texel_counts(b, lm, relative, target)
                    small = b.width * b.height <= 1024 * 1024
                    per_object[b.object_name] = dict(mesh_id=b.mesh_id, path=path, size=(b.width, b.height),
                                                     coverage=lm.coverage, rgb=lm.rgb if small else None,
                                                     error=lm.error if small else None, error_path=error_path,
                                                     texels=texels, texels_above=above,
                                                     error_above=above / texels if texels else 0.0)
                for w in writes:
                    w.result()  # the first failure, if any, as the call raised it
            for name, (path, error_path) in paths.items():
                images[name] = load_image(name + "_lightmap", path, pack)
                error_image = load_image(name + "_error", error_path, pack)
                error_image[materials.TAG] = materials.ERROR_IMAGE_TAG
                error_images[name] = error_image
            for name, o in per_object.items():
                o["image"] = images[name].name if name in images else None
                o["error_image"] = error_images[name].name if name in error_images else None
            stale = []
            if atlas_mode:
                images, error_images, uv_maps, stale = atlas.store(context, self, atlas_blocks, out_dir, pack,
                                                                   per_object)
                atlas_blocks.clear()
            else:
                atlas.forget(per_object)
            self._wire(context, images, error_images, target, uv_maps)
            atlas.remove_stale(stale)
            for name, lid in self.export.lsystems:
                obj = bpy.data.objects.get(name)
                if obj is not None:
                    lsystem.store_light(result, lid, obj)
            ol_info = {}
            selected = {o.name for o in context.view_layer.objects if o.select_get(view_layer=context.view_layer)}
            for group in self.export.ol_groups.values():
                if self.selected_only and not any(n in selected for n in group.objects):
                    continue  # a collection's OL that no selected object shares: kept as it was
                fname = export.safe_file_name(group.name) + "_ol.exr"
                path = os.path.join(out_dir, fname)
                result.write_ol_exr(group.group_id, path)
                st = result.ol_stats(group.group_id)
                ol_info[group.name] = dict(path=path, objects=list(group.objects), reason=group.reason,
                                           resolution=int(st["resolution"]), hits=int(st["hits"]))
                self.reports.info("orientation lightmap '%s' (%d x %d bins, %s): %s"
                                  % (group.name, st["resolution"], st["resolution"],
                                     ", ".join(group.objects), group.reason))
                self._wire_ol(context, group, load_image(group.name + "_ol", path, pack))
        finally:
            result.close()
            self.result = None
        # The photon pass's own rate (the whole bake also holds set-up, the direct pass and writing).
        photons_per_second = stats["photons_emitted"] / max(stats["seconds_trace"], 1e-9) \
            if stats["photons_emitted"] else 0.0
        noisiest = noisiest_objects(per_object)
        if float(stats["error_above"]) > properties.NOISY_SHARE:
            self.notices.append(noisy_message(stats, noisiest, per_object, self.settings["target_error"] > 0.0))
        shown_warnings = warning_lines(self.reports.items, self.notices)
        # Every distinct warning: the engine's, the add-on's and the notices (noisy texels, memory).
        warning_count = len({t for level, t in self.reports.items if level == 'WARNING'} | set(self.notices))
        times = self.stage_seconds(stats, time.perf_counter() - t_finish)
        scene[properties.STATS_KEY] = dict(
            photons_emitted=int(stats["photons_emitted"]), photons_per_second=float(photons_per_second),
            warning_count=warning_count,
            objects=len(self.export.baked),
            photon_hits=int(stats["photon_hits"]), rays_traced=int(stats["rays_traced"]),
            error_estimate=float(stats["error_estimate"]), error_direct=float(stats["error_direct"]),
            error_median=float(stats["error_median"]),
            error_p95=float(stats["error_p95"]), error_above=float(stats["error_above"]),
            target_error=float(self.settings["target_error"]), error_target=float(target),
            memory_estimate=float(stats["memory_estimate"]),
            noisiest=noisiest[0] if noisiest else "",
            noisiest_above=float(per_object[noisiest[0]]["error_above"]) if noisiest else 0.0,
            direct_samples=int(stats["direct_samples"]),
            triangles=int(self.export.triangles), **times,
            warning_lines="\n".join(shown_warnings))
        LAST.clear()
        LAST.update(stats=dict(stats, photons_per_second=photons_per_second, error_target=target,
                               warning_count=warning_count, triangles=int(self.export.triangles),
                               **times, **self.export_cpu_seconds()),
                    warnings=list(warnings), objects=per_object, output_dir=out_dir, ols=ol_info,
                    csg_objects=list(self.export.csg_objects),
                    lsystems=[name for name, _ in self.export.lsystems], noisiest=noisiest,
                    reports=list(self.reports.items) + [('WARNING', n) for n in self.notices])
        uvmaps.commit(self.created_uvs)  # kept: they belong to the baked lightmaps now
        self.created_uvs = []
        return LAST

    def texel_counts(self, baked, lm, relative, target):
        """An object's covered texels and those of them above twice the target error."""
        covered = lm.coverage > 0.0
        return int(np.count_nonzero(covered)), int(np.count_nonzero(relative[covered] > 2.0 * target))

    def export_cpu_seconds(self):
        """CPU seconds of the export and its stages, for LAST (scripts and benchmarks)."""
        out = {"cpu_seconds_" + k: float(v) for k, v in self.times.cpu.items()}
        out["cpu_seconds_export_other"] = max(0.0, self.cpu_seconds_export - sum(self.times.cpu.values()))
        out["cpu_seconds_export"] = self.cpu_seconds_export
        out["cpu_seconds_export_process"] = self.cpu_seconds_export_process
        return out

    def stage_seconds(self, stats, seconds_writeback):
        """Seconds per stage for the statistics: seconds_export and its parts seconds_export_<stage>
        (checks, uv, cages, depsgraph, meshes, refine, materials, world, other), the engine's seconds_setup,
        seconds_trace, seconds_direct and seconds_total, and seconds_writeback (EXRs, images,
        materials)."""
        out = {"seconds_" + k: float(v) for k, v in self.times.seconds.items()}
        out["seconds_export_other"] = max(0.0, self.seconds_export - self.times.total())
        out["seconds_export"] = float(self.seconds_export)
        for k in ("seconds_setup", "seconds_trace", "seconds_direct", "seconds_total"):
            out[k] = float(stats[k])
        out["seconds_writeback"] = float(seconds_writeback)
        return out

    def _wire(self, context, images, error_images, target, uv_maps):
        """Wire each baked object's materials to its lightmap image and its heat map, read through
        its uv_maps entry (default: the lightmap UV map). A material shared by baked objects shows
        the first one's image: all of them where they share an atlas page."""
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
            if len({images[o].name for o in objs}) > 1:
                self.reports.warning("material '%s' is shared by %s: its preview shows the lightmap of "
                                     "'%s' only (give each object its own material)"
                                     % (name, ", ".join("'%s'" % o for o in objs), objs[0]))
            for note in materials.wire_material(mat, images[objs[0]], engine, error_image=error_images[objs[0]],
                                                target_error=target,
                                                uv_map=uv_maps.get(objs[0], materials.LIGHTMAP_UV)):
                self.reports.warning(note)
            materials.set_preview(mat, context.scene.photonlm.preview_mode)


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
                materials.set_preview(mat, context.scene.photonlm.preview_mode)
                owned.add(mat.name)


def is_memory_warning(text):
    """The engine's warning that a bake comes close to the memory free."""
    return text.startswith("the bake may need about")


def relative_error(rgb, error):
    """Per-texel relative error: standard error / mean RGB value, 0 where the value is not above 0
    (a texel without light: the engine counts it as below any threshold)."""
    value = rgb.sum(axis=2, dtype=np.float32) / np.float32(3.0)
    out = np.zeros(value.shape, np.float32)
    np.divide(error, value, out=out, where=value > 0.0)
    return out


def error_image_pixels(relative):
    """The heat-map image of an object: its relative errors, or for a lightmap wider than
    ERROR_IMAGE_MAX the root mean square over blocks of k x k texels (k a power of two)."""
    h, w = relative.shape
    k = 1
    while max(h, w) > ERROR_IMAGE_MAX * k and h % (2 * k) == 0 and w % (2 * k) == 0:
        k *= 2
    if k == 1:
        return relative
    r2 = relative.astype(np.float64) ** 2
    return np.sqrt(r2.reshape(h // k, k, w // k, k).mean(axis=(1, 3))).astype(np.float32)


def write_error_exr(path, relative):
    """Write a (h, w) float32 array (row 0 = bottom) into R, G and B of an EXR of 16-bit floats (ZIP),
    atomically, with the engine's writer (no bpy: it may run on a thread). Half floats keep 3
    significant digits: plenty for a heat map, a tenth of the size."""
    bridge.get().write_heat_map_exr(path, relative)


def warning_lines(reports, notices, limit=20):
    """The bake's warnings for the panel, each once (engine warnings are already grouped), at
    most `limit` with a last line counting the rest."""
    lines = []
    for text in [t for level, t in reports if level == 'WARNING'] + list(notices):
        if text not in lines:
            lines.append(text)
    if len(lines) > limit:
        lines = lines[:limit - 1] + ["... and %d more (see the Info editor)" % (len(lines) - limit + 1)]
    return lines


def noisiest_objects(per_object, count=3):
    """Names of the noisy objects (more than properties.NOISY_SHARE of their texels above twice the
    target) holding the most such texels, first the one holding most: lowering its resolution
    helps the whole bake most."""
    noisy = [(o["texels_above"], name) for name, o in per_object.items()
             if o["texels_above"] > 0 and o["error_above"] > properties.NOISY_SHARE]
    return [name for _, name in sorted(noisy, key=lambda t: (-t[0], t[1]))][:count]


def noisy_message(stats, noisiest, per_object, has_target):
    """The warning for a bake with much of its lightmap above twice the target error."""
    names = ", ".join("'%s' (%.0f %%%s)" % (n, 100.0 * per_object[n]["error_above"], " of its texels" if i == 0 else "")
                      for i, n in enumerate(noisiest))
    return ("%.0f %% of the lightmap texels are above twice the %s (95th percentile %.0f %%)%s: lower "
            "the Resolution of %s, or raise the Time Budget or Max Photons%s"
            % (100.0 * float(stats["error_above"]), "target error" if has_target else "RMS error",
               100.0 * float(stats["error_p95"]), ", most of them on " + names if names else "",
               "these objects" if len(noisiest) > 1 else "this object" if noisiest else "the objects",
               " or lower the Target Error" if has_target else ""))


def load_image(name, path, pack=False):
    """Load (or reload) the float image `name` from `path`, colour space Non-Color. The image links
    its file relative to the .blend where the file is saved (the project folder can move), or is
    packed into the .blend (pack)."""
    image = bpy.data.images.get(name)
    if image is not None and image.source == 'FILE':
        if image.packed_file is not None:
            image.unpack(method='REMOVE')  # the new file replaces the packed copy
        image.filepath = path
        image.reload()
    else:
        if image is not None:
            image.name = name + ".old"  # generated: keep it, but free the name
        image = bpy.data.images.load(path, check_existing=False)
        image.name = name
    if bpy.data.is_saved:
        try:
            image.filepath = bpy.path.relpath(path)
        except ValueError:  # another drive than the .blend
            pass
    image.colorspace_settings.name = 'Non-Color'
    if hasattr(image, "use_half_precision"):
        image.use_half_precision = False
    image.alpha_mode = 'NONE'
    if pack:
        image.pack()
    return image
