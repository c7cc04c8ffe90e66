"""The scene file export (File > Export > PhotonLM scene (.json)): the scene a bake would build, as a scene file
(docs/scene-file.md) for `photonlm bake SCENE.json -o DIR` on a batch machine.

The export runs the bake's own export (export/scene.py's export_scene) against
photonlm.scene_file.SceneFileWriter, which has photonlm.Scene's methods and records the calls,
so the file holds exactly what a bake in Blender would trace: the same meshes (modifiers
applied, world space), materials, lights, world, CSG solids and OL groups, plus the scene's
bake settings. Automatic `lightmap` UV maps are made or refreshed first, as a bake does (they
are kept: the lightmaps baked from the file belong to them).

Where the lightmaps go: each object with a lightmap is a mesh named after the object, and
`photonlm bake` writes it to <object name>_lightmap.exr (unsafe characters as '_'). The file's
"metadata" lists, per object, the mesh index and that file name (and the OL groups'), for
scripts; File > Import > PhotonLM bake folder (bake/folder.py) brings the baked folder back by
the mesh names report.json lists.

Light groups (export/lightgroups.py) go into the file as its "light_groups" and each emitter's
"group"; `photonlm bake` then writes <mesh>_lightmap.<group>.exr beside each lightmap, and the
metadata lists the groups. With Directional on the file's settings say "directional": true and
`photonlm bake` writes <mesh>_lightmap_sh0..3.exr beside each lightmap (report.json's "sh").
"""
import os
import types

import bpy

from .. import bridge
from ..export import lightgroups
from ..export import scene as export
from ..uv import uvmaps
from ..version import VERSION


class ExportError(Exception):
    """The export could not be written; the message is for the user."""


CLI_FILE_LIMIT_MB = 256  # the largest file `photonlm bake` reads without --max-file-mb


def bake_command(path):
    """The command that bakes the scene file at path: with --max-file-mb where the file is larger
    than `photonlm bake` reads by default (inline meshes take about 300 bytes a triangle)."""
    mb = -(-os.path.getsize(path) // (1 << 20))
    return 'photonlm bake "%s" -o DIR%s' % (os.path.basename(path),
                                            " --max-file-mb %d" % mb if mb > CLI_FILE_LIMIT_MB else "")


def export_scene_file(context, path, reports=None, obj_threshold=200_000):
    """Write the current view layer as a scene file at path. Returns (path, metadata dict).
    Meshes with more than obj_threshold triangles go to OBJ files in <stem>_meshes/ beside it.
    Raises ExportError (nothing to export, the bridge is missing) or OSError (cannot write)."""
    reports = reports if reports is not None else export.Reports()
    try:
        photonlm = bridge.get()
    except RuntimeError as e:
        raise ExportError(str(e)) from e
    from photonlm.scene_file import SceneFileWriter  # noqa: E402 -- the bridge is on sys.path now
    objects = export.lightmap_objects(context)
    uvmaps.commit(uvmaps.ensure_for_scene(context, objects, reports))
    writer = SceneFileWriter(obj_threshold=obj_threshold)
    factory = types.SimpleNamespace(Scene=lambda: writer)
    try:
        lightgroups.check_names(export.light_group_plan(context))
    except ValueError as e:
        raise ExportError(str(e)) from None
    result = export.export_scene(context, factory, reports)
    if not result.manifest.baked and not writer.ol_groups:
        raise ExportError("nothing to export: no visible mesh object with 'Bake Lightmap' enabled "
                          "(or every one was skipped, see the reports)")
    refused = light_group_conflict(result.manifest) or \
        export.directional_conflict(result.manifest, context.scene.photonlm.directional)
    if refused:
        raise ExportError(refused)
    for name, _ in result.manifest.lsystems:  # not reached today: the writer refuses L-systems
        reports.warning("L-system '%s' is not in the scene file" % name)
    writer.set_settings(**export.bake_settings(context.scene))
    mesh_files, group_files = writer.output_files()
    writer.metadata = {
        "generator": "PhotonLM Blender add-on %s (photonlm %s)" % (
            ".".join(map(str, VERSION)), photonlm.version()),
        "blend_file": bpy.data.filepath,
        "blender_scene": context.scene.name,
        "lightmap_uv": uvmaps.LIGHTMAP_UV,
        "objects": [{"object": b.object_name, "mesh": b.mesh_id,
                     "lightmap_file": mesh_files[writer.meshes[b.mesh_id]["name"]]} for b in result.manifest.baked],
        "ol_groups": [{"name": g.name, "group": g.group_id, "objects": list(g.objects),
                       "ol_file": group_files[writer.ol_groups[g.group_id].get("name", "ol%d" % g.group_id)]}
                      for g in result.manifest.ol_groups.values()],
        "light_groups": list(result.manifest.light_groups),
    }
    # The CLI names files after the mesh and group names; the add-on after object names.
    try:
        path = writer.write(path)  # copies texture images next to the file
    finally:
        files = getattr(result, "texture_files", None)
        if files is not None and hasattr(files, "cleanup"):
            files.cleanup()
    reports.info("exported %d lightmapped objects, %d geometry-only objects, %d lights, %d OL groups, "
                 "%d CSG solids to %s" % (len(result.manifest.baked), result.geometry_only, result.lights,
                                          len(writer.ol_groups), len(writer.csg), path))
    return path, writer.metadata


def light_group_conflict(manifest):
    """Why `photonlm bake` would refuse the file's light groups (they split ordinary lightmaps only),
    or ""."""
    if not manifest.light_groups:
        return ""
    other = ("orientation lightmaps (%s)" % ", ".join("'%s'" % g.name for g in manifest.ol_groups.values())
             if manifest.ol_groups else
             "CSG solids (%s)" % ", ".join("'%s'" % n for n in manifest.csg_objects) if manifest.csg_objects else "")
    if not other:
        return ""
    return ("the scene has light groups (%s) and %s, which light groups do not split: bake it without "
            "light groups (clear the Light Groups of the view layer) or those objects as plain lightmaps"
            % (", ".join(manifest.light_groups), other))
