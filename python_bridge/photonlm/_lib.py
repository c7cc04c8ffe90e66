"""Loads libphotonlm and declares the C API (native/include/photonlm/photonlm.h) for ctypes.

Every function gets its argtypes/restype here, once. Handles are pointers to
distinct opaque structures, so passing a result where a scene is expected is
a ctypes.ArgumentError instead of a crash.
"""
import ctypes
import glob
import os
import sys
from ctypes import POINTER, c_char_p, c_double, c_float, c_int, c_int32, c_size_t, c_uint32, c_uint64, c_void_p

__all__ = ["LibraryNotFoundError", "lib", "library_path"]


class LibraryNotFoundError(OSError):
    """libphotonlm could not be found or loaded."""


_LIB_NAME = {"win32": "photonlm.dll", "darwin": "libphotonlm.dylib"}.get(sys.platform, "libphotonlm.so")


# The engine's own Embree 3, TBB, OpenEXR and OpenSubdiv (bundled beside it in the add-on) must
# serve its calls even where the host process loaded other versions first: Debian's Blender 4.3 and
# 5.2 link Embree 4, whose rtcNewDevice / rtcIntersect1 carry the same names, and without this the
# engine's calls bind to Blender's copies (photons hit nothing, some bakes crash). RTLD_DEEPBIND puts
# the library's own dependencies ahead of the process's global symbols for its lookups; RTLD_LOCAL
# keeps its symbols out of the host's. Sanitizer runtimes refuse DEEPBIND: PHOTONLM_DEEPBIND=0 loads
# the library plainly. docs/design/blender-side.md "The engine inside a host reaches its own libraries".
_LOAD_MODE = ctypes.RTLD_LOCAL
if hasattr(os, "RTLD_DEEPBIND") and os.environ.get("PHOTONLM_DEEPBIND", "1") != "0":
    _LOAD_MODE |= os.RTLD_DEEPBIND


def _find_library():
    env = os.environ.get("PHOTONLM_LIBRARY")
    here = os.path.dirname(os.path.abspath(__file__))
    beside = os.path.join(here, _LIB_NAME)
    # A versioned file (libphotonlm.so.0.1.0) next to the package is accepted too.
    candidates = ([env] if env else []) + [beside] + sorted(glob.glob(beside + ".*"))
    errors = []
    for path in candidates:
        if not os.path.isfile(path):
            continue
        try:
            return path, ctypes.CDLL(path, mode=_LOAD_MODE)
        except OSError as e:
            errors.append("%s: %s" % (path, e))
    raise LibraryNotFoundError(
        "photonlm: cannot load the native library. Looked at $PHOTONLM_LIBRARY (%s) and at %s%s"
        % (repr(env) if env else "not set", beside, "; " + "; ".join(errors) if errors else ""))


class Scene_(ctypes.Structure):
    """Opaque plm_scene."""


class Result_(ctypes.Structure):
    """Opaque plm_result."""


class Preview_(ctypes.Structure):
    """Opaque plm_preview."""


ScenePtr = POINTER(Scene_)
ResultPtr = POINTER(Result_)
PreviewPtr = POINTER(Preview_)
FloatPtr = POINTER(c_float)
UInt32Ptr = POINTER(c_uint32)


class _Sized(ctypes.Structure):
    """A struct that starts with its size (photonlm.h "Struct sizes"): made with struct_size =
    ctypes.sizeof(the struct); as array elements, which are made without __init__, use sized_array."""

    def __init__(self, *args, **kwargs):
        super().__init__(ctypes.sizeof(type(self)), *args, **kwargs)


def sized_array(cls, count):
    """An array of count structs of class cls, each with its struct_size set."""
    array = (cls * count)()
    for item in array:
        item.struct_size = ctypes.sizeof(cls)
    return array


class plm_light(_Sized):
    _fields_ = [
        ("struct_size", c_uint32),
        ("type", c_int32),
        ("color", c_float * 3),
        ("power", c_float),
        ("matrix", c_float * 16),
        ("radius", c_float),
        ("angle", c_float),
        ("size_x", c_float),
        ("size_y", c_float),
        ("spot_size", c_float),
        ("spot_blend", c_float),
    ]


class plm_lobe(_Sized):
    _fields_ = [
        ("struct_size", c_uint32),
        ("type", c_int32),
        ("color", c_float * 3),
        ("roughness", c_float),
        ("ior", c_float),
        ("abbe", c_float),
        ("weight", c_float),
    ]


class plm_bake_settings(_Sized):
    _fields_ = [
        ("struct_size", c_uint32),
        ("photon_count", c_uint64),
        ("max_bounces", c_uint32),
        ("seed", c_uint32),
        ("thread_count", c_uint32),
        ("dilation", c_uint32),
        ("target_error", c_double),
        ("time_budget", c_double),
        ("direct_samples", c_uint32),
        ("filter_radius", c_uint32),
        ("texel_value", c_uint32),
        ("sampler", c_uint32),
        ("directional", c_uint32),
    ]


class plm_bake_stats(_Sized):
    _fields_ = [
        ("struct_size", c_uint32),
        ("photons_emitted", c_uint64),
        ("photon_hits", c_uint64),
        ("rays_traced", c_uint64),
        ("paths_truncated", c_uint64),
        ("emitted_power", c_double),
        ("seconds_setup", c_double),
        ("seconds_trace", c_double),
        ("seconds_total", c_double),
        ("direct_samples", c_uint64),
        ("seconds_direct", c_double),
        ("error_estimate", c_double),
        ("error_direct", c_double),
        ("error_median", c_double),
        ("error_p95", c_double),
        ("error_above", c_double),
        ("memory_estimate", c_uint64),
        ("error_worst", c_double),
        ("error_worst_mesh", c_uint32),
    ]


class plm_csg_primitive(_Sized):
    _fields_ = [
        ("struct_size", c_uint32),
        ("shape", c_uint32),
        ("material", c_uint32),
        ("matrix", c_double * 12),
        ("major_radius", c_double),
        ("minor_radius", c_double),
    ]


class plm_csg_node(_Sized):
    _fields_ = [("struct_size", c_uint32), ("op", c_uint32), ("first", c_uint32), ("count", c_uint32)]


class plm_ol_stats(_Sized):
    _fields_ = [
        ("struct_size", c_uint32),
        ("resolution", c_uint32),
        ("mesh_count", c_uint32),
        ("hits", c_uint64),
        ("area", c_double),
        ("flux", c_double),
        ("orphan_flux", c_double),
    ]


class plm_lsystem_settings(_Sized):
    _fields_ = [
        ("struct_size", c_uint32),
        ("depth", c_uint32),
        ("seed", c_uint32),
        ("matrix", c_double * 12),
        ("step", c_double),
        ("angle", c_double),
        ("width", c_double),
        ("materials", POINTER(c_uint32)),
        ("material_count", c_uint32),
        ("ol_level", c_uint32),
        ("ol_resolution", c_uint32),
        ("cache_bytes", c_uint64),
    ]


class plm_lsystem_stats(_Sized):
    _fields_ = [
        ("struct_size", c_uint32),
        ("stubs", c_uint64),
        ("stub_instances", c_uint64),
        ("hits", c_uint64),
        ("classes", c_uint64),
        ("primitives", c_uint64),
        ("truncated", c_uint32),
        ("resolution", c_uint32),
        ("cache_hits", c_uint64),
        ("cache_misses", c_uint64),
        ("cache_bytes", c_uint64),
        ("class_bytes", c_uint64),
        ("area", c_double),
        ("flux", c_double),
    ]


# Every struct that carries its size, by its C name.
SIZED_STRUCTS = ("plm_light", "plm_lobe", "plm_bake_settings", "plm_bake_stats", "plm_csg_primitive", "plm_csg_node",
                 "plm_ol_stats", "plm_lsystem_settings", "plm_lsystem_stats")


# plm_status is a C enum: int-sized on every ABI we target.
status_t = c_int
progress_fn = ctypes.CFUNCTYPE(c_int, c_void_p, c_double, c_char_p)
preview_fn = ctypes.CFUNCTYPE(c_int, c_void_p, PreviewPtr)

library_path, lib = _find_library()

_SIGNATURES = {
    "plm_version": (c_char_p, []),
    "plm_status_string": (c_char_p, [status_t]),
    "plm_last_error": (c_char_p, []),
    "plm_scene_create": (status_t, [POINTER(ScenePtr)]),
    "plm_scene_release": (None, [ScenePtr]),
    "plm_scene_add_material": (status_t, [ScenePtr, c_char_p, FloatPtr, FloatPtr, UInt32Ptr]),
    "plm_scene_add_mesh": (status_t, [ScenePtr, c_char_p, FloatPtr, c_uint32, UInt32Ptr, c_uint32,
                                      FloatPtr, UInt32Ptr, c_uint32, c_uint32, UInt32Ptr]),
    "plm_scene_add_subdiv_mesh": (status_t, [ScenePtr, c_char_p, FloatPtr, c_uint32, UInt32Ptr, c_uint32,
                                             UInt32Ptr, FloatPtr, UInt32Ptr, UInt32Ptr, FloatPtr, c_uint32,
                                             c_uint32, c_uint32, c_uint32, UInt32Ptr]),
    "plm_scene_refine_subdiv_meshes": (status_t, [ScenePtr, c_uint32]),
    "plm_subdiv_refine": (status_t, [FloatPtr, c_uint32, UInt32Ptr, c_uint32, UInt32Ptr, FloatPtr, UInt32Ptr,
                                     FloatPtr, c_uint32, c_uint32, FloatPtr, c_uint32, UInt32Ptr, FloatPtr,
                                     c_uint32, UInt32Ptr, UInt32Ptr]),
    "plm_light_default": (None, [POINTER(plm_light), c_int]),
    "plm_scene_add_light": (status_t, [ScenePtr, c_char_p, POINTER(plm_light), UInt32Ptr]),
    "plm_scene_set_world": (status_t, [ScenePtr, FloatPtr]),
    "plm_scene_set_conventions": (status_t, [ScenePtr, c_int32]),
    "plm_scene_get_conventions": (status_t, [ScenePtr, POINTER(c_int32)]),
    "plm_scene_set_world_map": (status_t, [ScenePtr, FloatPtr, c_uint32, c_uint32, FloatPtr, c_float]),
    "plm_scene_set_world_map_file": (status_t, [ScenePtr, c_char_p, FloatPtr, c_float]),
    "plm_bake_settings_default": (None, [POINTER(plm_bake_settings)]),
    "plm_bake": (status_t, [ScenePtr, POINTER(plm_bake_settings), progress_fn, c_void_p,
                            POINTER(ResultPtr)]),
    "plm_bake_with_preview": (status_t, [ScenePtr, POINTER(plm_bake_settings), progress_fn, preview_fn, c_double,
                                         c_void_p, POINTER(ResultPtr)]),
    "plm_bake_shard": (status_t, [ScenePtr, POINTER(plm_bake_settings), c_uint32, c_uint32, c_char_p, c_char_p,
                                  progress_fn, c_void_p]),
    "plm_part_info": (status_t, [c_char_p, POINTER(plm_bake_settings), UInt32Ptr, UInt32Ptr, c_char_p, c_size_t]),
    "plm_bake_merge": (status_t, [ScenePtr, POINTER(c_char_p), c_uint32, c_uint32, progress_fn, c_void_p,
                                  POINTER(ResultPtr)]),
    "plm_preview_photons": (status_t, [PreviewPtr, POINTER(c_uint64)]),
    "plm_preview_lightmap_size": (status_t, [PreviewPtr, c_uint32, UInt32Ptr, UInt32Ptr]),
    "plm_preview_copy_lightmap": (status_t, [PreviewPtr, c_uint32, FloatPtr, POINTER(c_int)]),
    "plm_result_release": (None, [ResultPtr]),
    "plm_result_stats": (status_t, [ResultPtr, POINTER(plm_bake_stats)]),
    "plm_result_warning_count": (c_uint32, [ResultPtr]),
    "plm_result_warning": (c_char_p, [ResultPtr, c_uint32]),
    "plm_result_lightmap_size": (status_t, [ResultPtr, c_uint32, UInt32Ptr, UInt32Ptr]),
    "plm_result_copy_lightmap": (status_t, [ResultPtr, c_uint32, FloatPtr, FloatPtr, FloatPtr,
                                            FloatPtr]),
    "plm_result_write_exr": (status_t, [ResultPtr, c_uint32, c_char_p]),
    "plm_write_lightmap_exr": (status_t, [c_char_p, c_uint32, c_uint32, FloatPtr, FloatPtr, FloatPtr]),
    "plm_write_heat_map_exr": (status_t, [c_char_p, c_uint32, c_uint32, FloatPtr]),
    "plm_read_lightmap_exr": (status_t, [c_char_p, UInt32Ptr, UInt32Ptr, FloatPtr, FloatPtr, FloatPtr]),
    "plm_scene_add_ol_group": (status_t, [ScenePtr, c_char_p, c_uint32, UInt32Ptr]),
    "plm_scene_set_mesh_ol_group": (status_t, [ScenePtr, c_uint32, c_uint32]),
    "plm_scene_add_light_group": (status_t, [ScenePtr, c_char_p, UInt32Ptr]),
    "plm_scene_set_light_group": (status_t, [ScenePtr, c_uint32, c_uint32]),
    "plm_scene_set_mesh_light_group": (status_t, [ScenePtr, c_uint32, c_uint32]),
    "plm_scene_set_world_light_group": (status_t, [ScenePtr, c_uint32]),
    "plm_result_layer_count": (c_uint32, [ResultPtr]),
    "plm_result_layer_name": (c_char_p, [ResultPtr, c_uint32]),
    "plm_result_layer_error": (status_t, [ResultPtr, c_uint32, POINTER(c_double)]),
    "plm_result_copy_lightmap_layer": (status_t, [ResultPtr, c_uint32, c_uint32, FloatPtr, FloatPtr]),
    "plm_result_write_layer_exr": (status_t, [ResultPtr, c_uint32, c_uint32, c_char_p]),
    "plm_result_directional": (c_uint32, [ResultPtr]),
    "plm_result_copy_lightmap_sh": (status_t, [ResultPtr, c_uint32, c_uint32, FloatPtr]),
    "plm_result_write_sh_exr": (status_t, [ResultPtr, c_uint32, c_uint32, c_char_p]),
    "plm_lobe_default": (None, [POINTER(plm_lobe), c_int]),
    "plm_scene_add_material_lobe": (status_t, [ScenePtr, c_uint32, POINTER(plm_lobe)]),
    "plm_scene_set_material_diffuse": (status_t, [ScenePtr, c_uint32, c_int32, c_float]),
    "plm_scene_set_material_texture": (status_t, [ScenePtr, c_uint32, c_int, c_char_p, c_uint32]),
    "plm_scene_set_mesh_texture_uv": (status_t, [ScenePtr, c_uint32, FloatPtr]),
    "plm_scene_set_mesh_normals": (status_t, [ScenePtr, c_uint32, FloatPtr]),
    "plm_scene_set_mesh_smooth": (status_t, [ScenePtr, c_uint32, c_int]),
    "plm_scene_set_ol_group_backup": (status_t, [ScenePtr, c_uint32, c_int]),
    "plm_scene_set_ol_group_limit_area": (status_t, [ScenePtr, c_uint32, c_int]),
    "plm_scene_add_csg": (status_t, [ScenePtr, c_char_p, POINTER(plm_csg_primitive), c_uint32,
                                     POINTER(plm_csg_node), c_uint32, POINTER(c_uint32), c_uint32, c_uint32,
                                     POINTER(c_uint32)]),
    "plm_scene_set_csg_carrier": (status_t, [ScenePtr, c_uint32, c_uint32]),
    "plm_result_ol": (status_t, [ResultPtr, c_uint32, POINTER(FloatPtr), POINTER(FloatPtr), UInt32Ptr]),
    "plm_result_ol_bins": (status_t, [ResultPtr, c_uint32, POINTER(FloatPtr), POINTER(FloatPtr)]),
    "plm_result_ol_stats": (status_t, [ResultPtr, c_uint32, POINTER(plm_ol_stats)]),
    "plm_result_write_ol_exr": (status_t, [ResultPtr, c_uint32, c_char_p]),
    "plm_lsystem_settings_default": (None, [POINTER(plm_lsystem_settings)]),
    "plm_scene_add_lsystem": (status_t, [ScenePtr, c_char_p, c_char_p, POINTER(plm_lsystem_settings),
                                         UInt32Ptr]),
    "plm_lsystem_flatten": (status_t, [c_char_p, POINTER(plm_lsystem_settings), c_uint64, UInt32Ptr,
                                       POINTER(c_double), UInt32Ptr, POINTER(c_uint64), POINTER(c_int)]),
    "plm_result_lsystem_lookup": (status_t, [ResultPtr, c_uint32, c_uint64, FloatPtr, FloatPtr, FloatPtr]),
    "plm_result_lsystem_stats": (status_t, [ResultPtr, c_uint32, POINTER(plm_lsystem_stats)]),
}

for _name, (_restype, _argtypes) in _SIGNATURES.items():
    _f = getattr(lib, _name)
    _f.restype = _restype
    _f.argtypes = _argtypes
