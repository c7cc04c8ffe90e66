"""The write-back: a finished bake brought into the .blend, the same for a bake run in Blender
(bake/job.py) and for a bake folder from a farm (bake/folder.py).

    last = apply(context, manifest, result, reports, stage_seconds)

manifest (export/scene.py's Manifest) says what was baked: the objects with lightmaps (mesh id,
size, materials), the OL groups, L-system and CSG objects, the triangle count, Bake Selected and
the target error. result holds the lightmaps; what is read of it:
    result.stats, result.warnings         the engine's figures and warnings (photonlm.Result's names)
    result.lightmap(mesh_id)              a photonlm.Lightmap (rgb, error, hits, coverage)
    result.write_exr(mesh_id, path)       the lightmap file (R, G, B, error, hits)
    result.write_ol_exr(group_id, path), result.ol_stats(group_id)
    result.lsystem_lookup(...)            for L-system objects (only a bake in Blender has them)
    result.texel_counts                   optional {mesh id: (texels, texels above twice the target)}
    result.layers, result.lightmap_layer(mesh_id, k), result.write_layer_exr(mesh_id, k, path)
                                          light-group layers (optional: none without light groups)
    result.directional, result.lightmap_sh(mesh_id), result.write_sh_exr(mesh_id, band, path)
                                          directional lightmaps' SH bands (optional: none without)
    result.close()
a photonlm.Result as the engine returns it, or bake/folder.py's FolderResult over a folder's EXRs.

In order: the EXRs and heat maps are written (lightmaps of their own) or packed into atlas pages
(writeback/atlas.py), the images loaded (linked, or packed), the materials wired
(writeback/wiring.py), stale atlas pages removed, the L-system objects' light stored
(writeback/lsystem.py), the OLs written, loaded and wired, and the statistics kept on the scene
(writeback/record.py). Returns record.last(scene): the statistics and what was written.
"""
import concurrent.futures
import os
import time

import bpy
import numpy as np

from ..export.scene import safe_file_name
from ..export.meshes import LIGHTMAP_UV
from ..uv import uvmaps
from . import atlas, directional, images, lightgroups, lsystem, record, wiring


def apply(context, manifest, result, reports, stage_seconds, figures=None, outputs=None):
    """Bring `result` into the .blend (see the module text). stage_seconds: the seconds of the stages
    before the write-back (export, or reading a folder) for the statistics; figures: more figures
    for them (CPU seconds, where a folder came from); outputs: more entries for record.last().
    Closes the result. Returns record.last(scene), whose "notices" are the warnings to show last."""
    t_finish = time.perf_counter()
    scene = context.scene
    target_error = float(manifest.target_error)
    try:
        stats = result.stats
        warnings = result.warnings
        memory_warnings = [w for w in warnings if is_memory_warning(w)]
        for w in uvmaps.summarise_warnings([w for w in warnings if not is_memory_warning(w)]):
            reports.warning("engine: " + w)
        notices = ["engine: " + w for w in memory_warnings]
        out_dir = images.output_directory(scene)
        pack = scene.photonlm.pack_lightmaps or images.is_temporary_output(scene)
        # The heat map's scale and the engine's error_above: twice the target (twice the RMS error
        # without a target).
        target = target_error if target_error > 0.0 else float(stats["error_estimate"])
        known_counts = getattr(result, "texel_counts", None) or {}
        per_object = {}
        used_files = set()
        lightmap_images = {}
        error_images = {}
        atlas_mode = atlas.is_atlas(scene)
        atlas_blocks, uv_maps = {}, {}
        layers = list(getattr(result, "layers", None) or [])  # light groups (writeback/lightgroups.py)
        atlas_layers, layer_images = {}, {}
        with_sh = bool(getattr(result, "directional", False))  # writeback/directional.py
        atlas_sh, sh_images = {}, {}
        # The EXRs are written on threads (the engine's calls release the GIL): a small
        # object's two files cost about 0.8 ms each, which on a small scene is most of the
        # write-back. At most a few objects' writes wait at a time (each holds its heat map's
        # pixels). The images are loaded once all are written.
        writes, paths = [], {}
        workers = os.cpu_count() or 1
        with concurrent.futures.ThreadPoolExecutor(max_workers=workers) as pool:
            for b in manifest.baked:
                lm = result.lightmap(b.mesh_id)
                relative = images.relative_error(lm.rgb, lm.error)
                path = error_path = None
                if atlas_mode:  # written into atlas pages below
                    atlas_blocks[b.object_name] = lm
                    atlas_layers[b.object_name] = [result.lightmap_layer(b.mesh_id, i) for i in range(len(layers))]
                    if with_sh:
                        atlas_sh[b.object_name] = result.lightmap_sh(b.mesh_id)
                else:
                    base = safe_file_name(b.object_name)
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
                    writes.append(pool.submit(images.write_error_exr, error_path, images.error_image_pixels(relative)))
                    for i, layer in enumerate(layers):
                        writes.append(pool.submit(result.write_layer_exr, b.mesh_id, i,
                                                  lightgroups.layer_file(path, layer)))
                    if with_sh:
                        for band in directional.BANDS:
                            writes.append(pool.submit(result.write_sh_exr, b.mesh_id, band,
                                                      directional.band_file(path, band)))
                    paths[b.object_name] = (path, error_path)
                texels, above = known_counts.get(b.mesh_id) or texel_counts(lm, relative, target)
                small = b.width * b.height <= 1024 * 1024
                per_object[b.object_name] = dict(mesh_id=b.mesh_id, path=path, size=(b.width, b.height),
                                                 coverage=lm.coverage, rgb=lm.rgb if small else None,
                                                 error=lm.error if small else None, error_path=error_path,
                                                 texels=texels, texels_above=above,
                                                 error_above=above / texels if texels else 0.0,
                                                 relative_error=object_error(lm))
            for w in writes:
                w.result()  # the first failure, if any, as the call raised it
        for name, (path, error_path) in paths.items():
            lightmap_images[name] = images.load_image(name + "_lightmap", path, pack)
            error_image = images.load_image(name + "_error", error_path, pack)
            error_image[wiring.TAG] = wiring.ERROR_IMAGE_TAG
            error_images[name] = error_image
            layer_images[name] = _load_layers(name + "_lightmap", path, layers, pack, per_object[name])
            if with_sh:
                sh_images[name] = _load_sh(name + "_lightmap", path, pack, per_object[name])
        for name, o in per_object.items():
            o["image"] = lightmap_images[name].name if name in lightmap_images else None
            o["error_image"] = error_images[name].name if name in error_images else None
        stale = []
        if atlas_mode:
            lightmap_images, error_images, uv_maps, stale, layer_images, sh_images = atlas.store(
                context, manifest.selected_only, reports, atlas_blocks, out_dir, pack, per_object,
                layers=layers, layer_blocks=atlas_layers, sh_blocks=atlas_sh if with_sh else None)
            atlas_blocks.clear()
            atlas_layers.clear()
            atlas_sh.clear()
        else:
            atlas.forget(per_object)
        mix = None
        layer_errors = layer_error_figures(result, layers)
        notices.extend(noisy_layer_notices(layers, layer_errors, float(stats["error_estimate"]), target))
        if layers:
            lightgroups.sync_settings(scene, layers)
            mix = lightgroups.mix_group(scene, layers)
        _wire(context, manifest, reports, lightmap_images, error_images, target, uv_maps, layer_images, mix,
              sh_images)
        atlas.remove_stale(stale)
        if not with_sh:  # an earlier directional bake's bands no longer match these lightmaps
            directional.remove_stale_bands([o["path"] for o in per_object.values() if o.get("path")],
                                           [n + "_lightmap" for n in per_object] + list(
                                               {o["image"] for o in per_object.values() if o.get("image")}))
        for name, lid in manifest.lsystems:
            obj = bpy.data.objects.get(name)
            if obj is not None:
                lsystem.store_light(result, lid, obj)
        ol_info = {}
        selected = {o.name for o in context.view_layer.objects if o.select_get(view_layer=context.view_layer)}
        for group in manifest.ol_groups.values():
            if manifest.selected_only and not any(n in selected for n in group.objects):
                continue  # a collection's OL that no selected object shares: kept as it was
            fname = safe_file_name(group.name) + "_ol.exr"
            path = os.path.join(out_dir, fname)
            result.write_ol_exr(group.group_id, path)
            st = result.ol_stats(group.group_id)
            ol_info[group.name] = dict(path=path, objects=list(group.objects), reason=group.reason,
                                       resolution=int(st["resolution"]), hits=int(st["hits"]))
            reports.info("orientation lightmap '%s' (%d x %d bins, %s): %s"
                         % (group.name, st["resolution"], st["resolution"],
                            ", ".join(group.objects), group.reason))
            _wire_ol(context, manifest, reports, group, images.load_image(group.name + "_ol", path, pack))
    finally:
        result.close()
    # The photon pass's own rate (the whole bake also holds set-up, the direct pass and writing).
    photons_per_second = stats["photons_emitted"] / max(stats["seconds_trace"], 1e-9) \
        if stats["photons_emitted"] else 0.0
    noisiest = noisiest_objects(per_object)
    worst_name, worst_error = worst_object(stats, per_object)
    if float(stats["error_above"]) > record.NOISY_SHARE:
        notices.append(noisy_message(stats, noisiest, per_object, target_error > 0.0))
    shown_warnings = warning_lines(reports.items, notices)
    # Every distinct warning: the engine's, the add-on's and the notices (noisy texels, memory).
    warning_count = len({t for level, t in reports.items if level == 'WARNING'} | set(notices))
    times = dict(stage_seconds)
    for k in ("seconds_setup", "seconds_trace", "seconds_direct", "seconds_total"):
        times[k] = float(stats[k])
    times["seconds_writeback"] = float(time.perf_counter() - t_finish)
    all_figures = dict(stats)
    all_figures.update(
        photons_emitted=int(stats["photons_emitted"]), photons_per_second=float(photons_per_second),
        warning_count=warning_count,
        objects=len(manifest.baked),
        photon_hits=int(stats["photon_hits"]), rays_traced=int(stats["rays_traced"]),
        error_estimate=float(stats["error_estimate"]), error_direct=float(stats["error_direct"]),
        error_median=float(stats["error_median"]),
        error_p95=float(stats["error_p95"]), error_above=float(stats["error_above"]),
        target_error=target_error, error_target=float(target),
        memory_estimate=float(stats["memory_estimate"]),
        noisiest=noisiest[0] if noisiest else "",
        noisiest_above=float(per_object[noisiest[0]]["error_above"]) if noisiest else 0.0,
        worst_object=worst_name, error_worst=worst_error,
        direct_samples=int(stats["direct_samples"]),
        triangles=int(manifest.triangles), **times, light_layers=",".join(layers), directional=int(with_sh),
        light_layer_errors=",".join("%.6g" % e for e in layer_errors),
        warning_lines="\n".join(shown_warnings))
    all_figures.update(figures or {})
    record.store(scene, all_figures, dict(
        warnings=list(warnings), objects=per_object, output_dir=out_dir, ols=ol_info,
        csg_objects=list(manifest.csg_objects), lsystems=[name for name, _ in manifest.lsystems],
        noisiest=noisiest, reports=list(reports.items) + [('WARNING', n) for n in notices],
        notices=notices, **(outputs or {})))
    return record.last(scene)


def layer_error_figures(result, layers):
    """Each light-group layer's estimated relative error (the engine's), [] where the result has no
    layers or gives no errors (a bake folder)."""
    if not layers or not hasattr(result, "layer_error"):
        return []
    return [float(result.layer_error(k)) for k in range(len(layers))]


def noisy_layer_notices(layers, errors, whole_error, target):
    """A notice for each layer estimated at more than twice the target (or twice the bake's own
    error without one): a group with a small share of the light is that much noisier."""
    limit = 2.0 * (target if target > 0.0 else whole_error)
    return ["light group '%s': its layer's estimated error is %.1f %% (the lightmap's %.1f %%): a group with "
            "a small share of the light is noisier relative to its own light; lower the Target Error for a "
            "clean layer" % ("Other Lights" if name == "default" else name, 100.0 * e, 100.0 * whole_error)
            for name, e in zip(layers, errors) if limit > 0.0 and e > limit]


def object_error(lm):
    """An object's estimated relative RMS error over its covered texels, relative to its own mean
    (what the target error bounds): sqrt(mean(error^2)) / mean(value)."""
    covered = lm.coverage > 0.0
    if not np.any(covered):
        return 0.0
    mean = float(np.mean(lm.rgb[covered]))
    return float(np.sqrt(np.mean(np.square(lm.error[covered], dtype=np.float64))) / mean) if mean > 0.0 else 0.0


def worst_object(stats, per_object):
    """(name, relative error) of the noisiest object: the one the engine names (stats error_worst_mesh,
    or a bake folder's worst_object), else the baked object with the largest relative_error; ('', 0)
    without objects."""
    mesh = stats.get("error_worst_mesh")
    for name, o in per_object.items():
        if (mesh is not None and o["mesh_id"] == mesh) or name == stats.get("worst_object"):
            return name, float(stats.get("error_worst") or o["relative_error"])
    if not per_object:
        return "", 0.0
    name = max(per_object, key=lambda n: (per_object[n]["relative_error"], n))
    return name, float(per_object[name]["relative_error"])


def texel_counts(lm, relative, target):
    """An object's covered texels and those of them above twice the target error."""
    covered = lm.coverage > 0.0
    return int(np.count_nonzero(covered)), int(np.count_nonzero(relative[covered] > 2.0 * target))


def _load_layers(base, path, layers, pack, entry):
    """Load the light-group layers of the lightmap file `path` as images <base>.<layer>; note them in the
    object's per_object entry. Returns [(layer, image)]."""
    out = []
    for layer in layers:
        layer_path = lightgroups.layer_file(path, layer)
        out.append((layer, images.load_image(lightgroups.layer_image_name(base, layer), layer_path, pack)))
    entry["layers"] = {layer: dict(image=image.name, path=lightgroups.layer_file(path, layer)) for layer, image in out}
    return out


def _load_sh(base, path, pack, entry):
    """Load the L1 bands of the lightmap file `path` as images <base>_sh1 .. _sh3; note them in the
    object's per_object entry. Returns [image per band]."""
    out = [images.load_image(directional.band_image_name(base, band), directional.band_file(path, band), pack)
           for band in directional.BANDS]
    entry["sh"] = [dict(band=band, image=image.name, path=directional.band_file(path, band))
                   for band, image in zip(directional.BANDS, out)]
    return out


def _wire(context, manifest, reports, lightmap_images, error_images, target, uv_maps, layer_images=None, mix=None,
          sh_images=None):
    """Wire each baked object's materials to its lightmap image and its heat map, read through
    its uv_maps entry (default: the lightmap UV map). A material shared by baked objects shows
    the first one's image: all of them where they share an atlas page. With light groups (mix: the
    node group of writeback/lightgroups.py) the preview sums the object's layer_images instead; with
    directional lightmaps (sh_images: the L1 bands' images by object) it evaluates them at the
    material's shading normal (writeback/directional.py)."""
    layer_images = layer_images or {}
    sh_images = sh_images or {}
    engine = context.scene.render.engine
    owners = {}
    for b in sorted(manifest.baked, key=lambda b: b.object_name):
        for name in b.material_names:
            if name is not None:
                owners.setdefault(name, [])
                if b.object_name not in owners[name]:
                    owners[name].append(b.object_name)
        if not any(b.material_names):
            reports.warning("object '%s' has no material: lightmap baked, no preview" % b.object_name)
    for name, objs in owners.items():
        mat = bpy.data.materials.get(name)
        if mat is None:
            continue
        if len({lightmap_images[o].name for o in objs}) > 1:
            reports.warning("material '%s' is shared by %s: its preview shows the lightmap of "
                            "'%s' only (give each object its own material)"
                            % (name, ", ".join("'%s'" % o for o in objs), objs[0]))
        for note in wiring.wire_material(mat, lightmap_images[objs[0]], engine, error_image=error_images[objs[0]],
                                         target_error=target, uv_map=uv_maps.get(objs[0], LIGHTMAP_UV),
                                         layers=layer_images.get(objs[0]) if mix is not None else None, mix=mix,
                                         sh=sh_images.get(objs[0])):
            reports.warning(note)
        wiring.set_preview(mat, context.scene.photonlm.preview_mode)


def _wire_ol(context, manifest, reports, group, image):
    """Objects of an OL group without a lightmap image of their own (instances, objects without
    'Bake Lightmap'): their materials look the OL up by the world normal (node group
    'PhotonLM OL Lookup'), unless a baked lightmap already owns the material."""
    owned = {n for b in manifest.baked for n in b.material_names if n is not None}
    baked = {b.object_name for b in manifest.baked}
    engine = context.scene.render.engine
    for name in group.objects:
        obj = bpy.data.objects.get(name)
        if obj is None or name in baked:
            continue
        for slot in obj.material_slots:
            mat = slot.material
            if mat is None or mat.name in owned:
                continue
            for note in wiring.wire_material(mat, image, engine, orientation=True):
                reports.warning(note)
            wiring.set_preview(mat, context.scene.photonlm.preview_mode)
            owned.add(mat.name)


def is_memory_warning(text):
    """The engine's warning that a bake comes close to the memory free."""
    return text.startswith("the bake may need about")


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
    """Names of the noisy objects (more than record.NOISY_SHARE of their texels above twice the
    target) holding the most such texels, first the one holding most: lowering its resolution
    helps the whole bake most."""
    noisy = [(o["texels_above"], name) for name, o in per_object.items()
             if o["texels_above"] > 0 and o["error_above"] > record.NOISY_SHARE]
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
