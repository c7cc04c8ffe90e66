"""The record of the last bake: its statistics in one place, the scene's ID property STATS_KEY.

stats(scene) reads them (a plain dict; {} before the first bake): the engine's figures
(photonlm.Result.stats: photons, rays, errors, memory estimate, seconds per stage) and the add-on's
(photons per second, the target, the noisiest object, warnings, export stages, CPU seconds, and
for an imported bake folder where it came from). The panel, the read-only properties and scripts
read them through it, and they travel with the .blend.

last(scene) adds what the last write-back in this Blender session brought into that scene, for
scripts and tests: per object its mesh id, image names, EXR paths, size, coverage mask and (for
lightmaps up to 1024 x 1024) its texels and errors; the OLs, CSG objects, L-systems, the warnings
and reports. Those arrays are too large for the .blend and are held only while Blender runs.
"""
import bpy

STATS_KEY = "photonlm_last_bake"  # ID property on the scene: the last bake's statistics
# The Last Bake box suggests what to do when more than this share of the texels is above
# twice the target error.
NOISY_SHARE = 0.10
_INT32 = 2 ** 31

_OUTPUTS = {}  # scene key -> the last write-back's outputs in that scene (kept in memory, not saved)


def _scene_key(scene):
    uid = getattr(scene, "session_uid", None)
    return uid if uid is not None else scene.name_full


def _id_value(value):
    """A value an ID property can hold: ints beyond 32 bits as floats."""
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, int) and not -_INT32 <= value < _INT32:
        return float(value)
    return value


def stats(scene):
    """The last bake's statistics on the scene, as a plain dict ({} where it has none)."""
    stored = scene.get(STATS_KEY)
    if not stored:
        return {}
    return stored.to_dict() if hasattr(stored, "to_dict") else dict(stored)


def store(scene, figures, outputs):
    """Keep a write-back's statistics on the scene and its outputs for last()."""
    scene[STATS_KEY] = {k: _id_value(v) for k, v in figures.items()}
    _OUTPUTS[_scene_key(scene)] = outputs


def last(scene=None):
    """The last bake of the scene (default: the context's): its outputs (objects, ols, output_dir,
    warnings, reports, ...) with its statistics under "stats"; {} where none was made since Blender started."""
    scene = bpy.context.scene if scene is None else scene
    outputs = _OUTPUTS.get(_scene_key(scene))
    if outputs is None:
        return {}
    return dict(outputs, stats=stats(scene))
