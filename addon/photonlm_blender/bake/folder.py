"""File > Import > PhotonLM bake folder: the lightmaps a farm (or any batch machine) baked from an
exported scene file (`photonlm bake --shard K/N` and `photonlm merge ... -o DIR`, or `photonlm bake
SCENE.json -o DIR`), brought into the .blend as a bake inside Blender brings its own.

The folder's report.json lists each lightmapped mesh (`name`, `file`, `size`) and OL group. The
scene-file export names each lightmapped mesh after its object (and an OL group after its object,
or "collection <name>" for a collection's), so a report entry belongs to the object of that name.
Everything is read and checked first (the report, every EXR: present, readable, of the size the
report gives) into a manifest (export/scene.py's Manifest, as an export makes it) and a
FolderResult (what the write-back reads of a result); only then does the .blend change, through
writeback/apply.py, the in-Blender bake's own write-back: the EXRs are copied into the scene's lightmap folder under the add-on's names, the
heat-map images made from their error channel, the images loaded (linked, or packed with Pack),
the materials wired, and the statistics of the report stored for the Last Bake panel.

Objects in the report that the .blend lacks (a report of another scene, a renamed object) are
skipped with a warning each; a folder without report.json, a report that is no bake report, a
missing, unreadable or mis-sized EXR and a folder of shard part files (not yet merged) are
refused with a message naming what is wrong, and nothing changes. A bake with light groups
(report.json's light_groups, each mesh's layers) brings its layers too, as a bake in Blender does,
and a directional bake (report.json's settings.directional, each mesh's "sh": its four SH band
files) its bands.
"""
import glob
import json
import os
import shutil
import time

import bpy
import numpy as np

from .. import bridge
from ..export import scene as export
from ..export.meshes import LIGHTMAP_UV
from ..writeback import apply, atlas

REPORT = "report.json"
PART_PATTERN = "part-*-of-*.plmpart"
COLLECTION_PREFIX = "collection "  # export/scene.py's _ol_group names a collection's OL group "collection <name>"


class FolderError(Exception):
    """The folder cannot be imported; the message names what is wrong and where."""


def _part_files(folder):
    """Shard part files in the folder or its parts/ subfolder (scripts/slurm_bake.sh's layout)."""
    found = sorted(glob.glob(os.path.join(glob.escape(folder), PART_PATTERN)))
    return found or sorted(glob.glob(os.path.join(glob.escape(folder), "parts", PART_PATTERN)))


def read_report(folder):
    """The folder's report.json as a dict; FolderError naming what is wrong."""
    if not os.path.isdir(folder):
        raise FolderError("'%s' is not a folder" % folder)
    path = os.path.join(folder, REPORT)
    if not os.path.isfile(path):
        parts = _part_files(folder)
        if parts:
            where = os.path.dirname(parts[0])
            raise FolderError(
                "'%s' holds %d shard part file%s (%s...) but no merged bake: this is a folder of shard parts, "
                "not a merged one. Merge them first (photonlm merge \"%s\" -o OUT) and import OUT"
                % (folder, len(parts), "" if len(parts) == 1 else "s", os.path.basename(parts[0]), where))
        raise FolderError("'%s' has no %s: not a folder written by photonlm bake or photonlm merge" % (folder, REPORT))
    try:
        with open(path, "rb") as f:
            report = json.loads(f.read().decode("utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as e:
        raise FolderError("cannot read %s: %s" % (path, e)) from None
    if not isinstance(report, dict) or not isinstance(report.get("meshes"), list) \
            or not isinstance(report.get("stats"), dict):
        raise FolderError("%s is not a photonlm bake report (no 'meshes' list or 'stats')" % path)
    return report


def _number(report, path, *keys, default=0.0):
    """report[keys[0]][keys[1]]... as a float (default where missing); FolderError if not a number."""
    value = report
    for k in keys:
        if not isinstance(value, dict) or k not in value:
            return default
        value = value[k]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise FolderError("%s: %s is %r, not a number" % (path, ".".join(keys), value))
    return value


def result_stats(report, path):
    """The report's statistics under the names of photonlm.Result.stats."""
    n = lambda *keys: _number(report, path, *keys)  # noqa: E731
    return dict(photons_emitted=int(n("photons", "emitted")), photon_hits=int(n("photons", "hits")),
                rays_traced=int(n("photons", "rays")), paths_truncated=int(n("photons", "truncated")),
                emitted_power=float(n("emitted_power")), direct_samples=int(n("direct_samples")),
                seconds_setup=float(n("times", "setup")), seconds_trace=float(n("times", "trace")),
                seconds_direct=float(n("times", "direct")), seconds_total=float(n("times", "total")),
                error_estimate=float(n("stats", "error_estimate")), error_direct=float(n("stats", "error_direct")),
                error_median=float(n("stats", "median")), error_p95=float(n("stats", "p95")),
                error_above=float(n("stats", "above_twice_target")),
                memory_estimate=float(n("stats", "memory_estimate")),
                # The noisiest object by name (reports of older versions have none).
                error_worst=float(report["stats"].get("worst_object_error") or 0.0),
                worst_object=report["stats"].get("worst_object") or "")


def coverage_mask(hits):
    """Which texels lie inside the UV islands as far as the EXR tells: those with photon hits (the
    engine records hits only there; dilated texels hold none)."""
    return (hits > 0.0).astype(np.float32)


class FolderResult:
    """What the write-back (writeback/apply.py) reads of a result, from a bake folder: the statistics
    and warnings of its report, the lightmaps of its EXRs, the texel counts of its report; "writing"
    an EXR copies the folder's file."""

    def __init__(self, stats, warnings, lightmaps, ols, texel_counts, layers=(), layer_files=None, sh_files=None):
        self.stats = stats
        self.warnings = warnings
        self._lightmaps = lightmaps  # mesh id -> (EXR path, photonlm.Lightmap)
        self.layers = list(layers)   # the light groups' layer names (report.json's light_groups)
        self._layer_files = layer_files or {}  # mesh id -> [EXR path per layer]
        self._ols = ols              # group id -> (EXR path, {"resolution", "hits"})
        self._sh_files = sh_files or {}  # mesh id -> [EXR path per SH band 0..3] (directional bakes)
        self.directional = bool(self._sh_files)
        # mesh id -> (texels, texels above twice the target) from the report (the engine's counts);
        # for a report without them the write-back counts the texels with photon hits (a covered
        # texel no photon reached then counts as outside).
        self.texel_counts = texel_counts

    def lightmap(self, mesh_id):
        return self._lightmaps[mesh_id][1]

    def write_exr(self, mesh_id, path):
        _copy(self._lightmaps[mesh_id][0], path)

    def lightmap_layer(self, mesh_id, layer):
        lm = bridge.get().read_lightmap_exr(self._layer_files[mesh_id][layer])
        return lm.rgb, lm.error

    def write_layer_exr(self, mesh_id, layer, path):
        _copy(self._layer_files[mesh_id][layer], path)

    def lightmap_sh(self, mesh_id):
        """The SH bands as photonlm.Result.lightmap_sh gives them: (4, h, w, 3)."""
        return np.stack([bridge.get().read_lightmap_exr(f).rgb for f in self._sh_files[mesh_id]])

    def write_sh_exr(self, mesh_id, band, path):
        _copy(self._sh_files[mesh_id][band], path)

    def write_ol_exr(self, group_id, path):
        _copy(self._ols[group_id][0], path)

    def ol_stats(self, group_id):
        return self._ols[group_id][1]

    def close(self):
        self._lightmaps = {}


def _copy(source, path):
    """Copy source to path atomically (nothing where both are the same file)."""
    if os.path.exists(path) and os.path.samefile(source, path):
        return
    tmp = path + ".tmp-import"
    try:
        shutil.copyfile(source, tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def _layer_names(report, report_path):
    """The light groups' layer names of a report (its light_groups), [] without light groups."""
    groups = report.get("light_groups") or []
    names = [g.get("name") if isinstance(g, dict) else None for g in groups]
    if not isinstance(groups, list) or not all(isinstance(n, str) and n for n in names):
        raise FolderError("%s: light_groups is not a list of groups with names: %s"
                          % (report_path, json.dumps(groups)[:200]))
    return names


def _materials_of(obj):
    """Names of the materials on the object's slots, as the export reads them (may repeat)."""
    mats = [s.material for s in obj.material_slots] or list(obj.data.materials)
    return [m.name if m is not None else None for m in mats]


def _string(value):
    return value if isinstance(value, str) else None


class BakeFolder:
    """A finished bake read from a folder: finish(context) brings it in through the write-back. The
    constructor reads and checks everything and changes nothing; FolderError (or RuntimeError: no
    bridge) if it cannot."""

    def __init__(self, context, folder):
        t0 = time.perf_counter()
        self.reports = export.Reports()
        self.photonlm = bridge.get()
        self.folder = os.path.normpath(bpy.path.abspath(folder))
        report_path = os.path.join(self.folder, REPORT)
        report = read_report(self.folder)
        settings = report.get("settings") if isinstance(report.get("settings"), dict) else {}
        self.notices = []
        self.report = report
        self.manifest = export.Manifest(target_error=float(_number(settings, report_path, "target_error")))
        stats = result_stats(report, report_path)
        warnings = report.get("warnings") if isinstance(report.get("warnings"), list) else []
        warnings = [w for w in warnings if isinstance(w, str)]
        lightmaps, ols, missing = {}, {}, []
        counts = {}  # mesh id -> (texels, texels above twice the target) from the report
        layers = _layer_names(report, report_path)
        layer_files = {}  # mesh id -> [EXR path per layer]
        directional = settings.get("directional") is True
        sh_files = {}  # mesh id -> [EXR path per SH band] (directional bakes)
        for i, entry in enumerate(report["meshes"]):
            name = _string(entry.get("name")) if isinstance(entry, dict) else None
            file = _string(entry.get("file")) if isinstance(entry, dict) else None
            size = entry.get("size") if isinstance(entry, dict) else None
            if name is None or file is None or os.path.basename(file) != file or not isinstance(size, list) \
                    or len(size) != 2 or not all(isinstance(s, int) and s > 0 for s in size):
                raise FolderError("%s: meshes[%d] is not a lightmap entry ('name', 'file' in the folder, "
                                  "'size' [w, h]): %s" % (report_path, i, json.dumps(entry)[:200]))
            obj = bpy.data.objects.get(name)
            if obj is None or obj.type != 'MESH':
                missing.append(name)
                self.reports.warning("the bake's object '%s' (%s) is %s in this .blend: skipped"
                                     % (name, file, "not a mesh object" if obj is not None else "not"))
                continue
            if obj.data.uv_layers.get(LIGHTMAP_UV) is None:
                self.reports.warning("object '%s' has no '%s' UV map, so its lightmap cannot line up: skipped "
                                     "(save the .blend after exporting the scene file: the export makes the map)"
                                     % (name, LIGHTMAP_UV))
                continue
            res = int(obj.photonlm.resolution)
            if res > 0 and tuple(size) != (res, res):
                self.reports.warning("object '%s' has a Resolution of %d, its lightmap in the bake is %d x %d: "
                                     "changed since the export?" % (name, res, size[0], size[1]))
            path = os.path.join(self.folder, file)
            lm = self._read_exr(name, path, tuple(size))
            lightmaps[i] = (path, self.photonlm.Lightmap(lm.rgb, lm.error, lm.hits, coverage_mask(lm.hits)))
            layer_files[i] = self._layer_files(name, entry, layers, report_path, tuple(size))
            if directional:
                sh_files[i] = self._sh_files(name, entry, report_path, tuple(size))
            pair = (entry.get("texels"), entry.get("texels_above_twice_target"))
            if all(isinstance(c, int) and not isinstance(c, bool) for c in pair):
                counts[i] = pair
            self.manifest.baked.append(export.BakedObject(obj, i, size[0], size[1], _materials_of(obj)))
        for i, entry in enumerate(report.get("ol_groups", []) or []):
            group = self._ol_group(i, entry, report_path, context.view_layer)
            if group is None:
                continue
            path = os.path.join(self.folder, entry["file"])
            self._read_exr("OL '%s'" % entry["name"], path, None)
            resolution = int(_number(entry, report_path, "resolution"))
            ols[i] = (path, {"resolution": resolution, "hits": int(_number(entry, report_path, "hits"))})
        if not self.manifest.baked and not self.manifest.ol_groups:
            if missing and len(missing) == len(report["meshes"]):
                raise FolderError("none of the %d objects of %s is a mesh object in this .blend (%s%s): the bake of "
                                  "another scene (%s)?" % (len(missing), report_path, ", ".join(missing[:3]),
                                                           ", ..." if len(missing) > 3 else "",
                                                           report.get("scene", "scene unknown")))
            raise FolderError("%s lists no lightmap this .blend can take (see the warnings)" % report_path)
        if atlas.is_atlas(context.scene):
            try:
                atlas.check(context.scene, self.manifest.baked, False)
            except atlas.AtlasError as e:
                raise FolderError(str(e)) from None
        self.result = FolderResult(stats, warnings, lightmaps, ols, counts, layers, layer_files, sh_files)
        self.seconds_read = time.perf_counter() - t0

    def _read_exr(self, what, path, size):
        """Check that the EXR is there, readable and of size (w, h) (None: any); return its Lightmap."""
        if not os.path.isfile(path):
            raise FolderError("the lightmap of %s is missing: %s (the report lists it; is the folder whole?)"
                              % (what if what.startswith("OL") else "'%s'" % what, path))
        try:
            lm = self.photonlm.read_lightmap_exr(path)
        except Exception as e:  # noqa: BLE001 -- the engine's message names the file and the fault
            raise FolderError("cannot read the lightmap of %s: %s" % (what if what.startswith("OL") else "'%s'" % what,
                                                                     getattr(e, "message", None) or e)) from None
        if size is not None and (lm.rgb.shape[1], lm.rgb.shape[0]) != size:
            raise FolderError("the lightmap of '%s' (%s) is %d x %d, the report says %d x %d"
                              % (what, path, lm.rgb.shape[1], lm.rgb.shape[0], size[0], size[1]))
        return lm

    def _layer_files(self, name, entry, layers, report_path, size):
        """The EXRs of a mesh entry's light-group layers, in the order of `layers` (checked as the
        lightmap is); FolderError naming a layer the entry lacks."""
        given = {}
        for item in entry.get("layers") or []:
            if isinstance(item, dict) and isinstance(item.get("group"), str) and isinstance(item.get("file"), str) \
                    and os.path.basename(item["file"]) == item["file"]:
                given[item["group"]] = item["file"]
        paths = []
        for layer in layers:
            if layer not in given:
                raise FolderError("%s: the lightmap of '%s' has no layer '%s' (the report's light_groups name it)"
                                  % (report_path, name, layer))
            path = os.path.join(self.folder, given[layer])
            self._read_exr("%s' layer '%s" % (name, layer), path, size)
            paths.append(path)
        return paths

    def _sh_files(self, name, entry, report_path, size):
        """The EXRs of a mesh entry's four SH bands (its "sh"), checked as the lightmap is; FolderError
        where the entry lacks them."""
        files = entry.get("sh")
        if not isinstance(files, list) or len(files) != 4 or not all(
                isinstance(f, str) and os.path.basename(f) == f for f in files):
            raise FolderError("%s: the bake is directional, but the lightmap of '%s' has no list of its four SH "
                              "band files ('sh')" % (report_path, name))
        paths = [os.path.join(self.folder, f) for f in files]
        for band, path in enumerate(paths):
            self._read_exr("%s' SH band '%d" % (name, band), path, size)
        return paths

    def _ol_group(self, i, entry, report_path, view_layer):
        """The export.OlGroup of report entry ol_groups[i] (its collection's or its object's), or None
        with a warning when the .blend has neither."""
        name = _string(entry.get("name")) if isinstance(entry, dict) else None
        file = _string(entry.get("file")) if isinstance(entry, dict) else None
        if name is None or file is None or os.path.basename(file) != file:
            raise FolderError("%s: ol_groups[%d] is not an OL entry ('name', 'file' in the folder): %s"
                              % (report_path, i, json.dumps(entry)[:200]))
        coll = bpy.data.collections.get(name[len(COLLECTION_PREFIX):]) if name.startswith(COLLECTION_PREFIX) else None
        if coll is not None:
            group = export.OlGroup(i, "collection_" + coll.name, "collection '%s' (from the bake folder)" % coll.name)
            group.objects = sorted(o.name for o in coll.objects
                                   if o.type in export.GEOMETRY_TYPES and export.is_renderable(o, view_layer))
        elif bpy.data.objects.get(name) is not None:
            group = export.OlGroup(i, name, "object '%s' (from the bake folder)" % name)
            group.objects = [name]
        else:
            self.reports.warning("the bake's orientation lightmap '%s' (%s) belongs to no object or collection "
                                 "of this .blend: skipped" % (name, file))
            return None
        self.manifest.ol_groups[("report", i)] = group
        return group

    def abort(self, context):
        """Nothing to undo before finish(): release the lightmaps read."""
        if self.result is not None:
            self.result.close()
            self.result = None

    def finish(self, context):
        """Bring the bake in (writeback/apply.py) with the report's stage times; returns the record."""
        wall = _number(self.report, self.folder, "times", "wall")
        result, self.result = self.result, None
        last = apply.apply(context, self.manifest, result, self.reports, {"seconds_import": float(self.seconds_read)},
                           figures=dict(imported_from=self.folder, seconds_wall=float(wall)),
                           outputs=dict(imported_from=self.folder))
        self.notices = last["notices"]
        return last


def import_folder(context, folder):
    """Import the bake folder; returns (the record, reports). Raises FolderError or RuntimeError."""
    job = BakeFolder(context, folder)
    try:
        return job.finish(context), job.reports
    except BaseException:
        job.abort(context)
        raise
