"""photonlm: Python bridge to the photon-lightmap GI baker (ctypes + numpy, no compiled extension).

    import photonlm
    with photonlm.Scene() as scene:
        mat = scene.add_material(albedo=(0.8, 0.8, 0.8))
        mesh = scene.add_mesh("floor", positions, triangles, lightmap_uv=uv, resolution=256)
        scene.add_light("SUN", power=3.0, matrix=sun.matrix_world)
        with scene.bake(photons=2_000_000) as result:
            lm = result.lightmap(mesh)         # lm.rgb is (h, w, 3), row 0 = v near 0
            result.write_exr(mesh, "floor.exr")

The library is found through $PHOTONLM_LIBRARY (full path) or next to this file.
Units and conventions are those of native/include/photonlm/photonlm.h (Cycles' units;
a lightmap texel holds irradiance / pi). Arrays are passed to C without copies when
they already have the right dtype and are C-contiguous.
"""
import collections
import ctypes
import operator
import os

import numpy as np

from . import _lib
from ._lib import LibraryNotFoundError, library_path

__all__ = ["version", "PhotonlmError", "BakeCancelled", "LibraryNotFoundError", "Scene", "Result", "Preview",
           "Lightmap", "OrientationLightmap", "library_path", "lsystem_flatten", "LSYSTEM_SHAPES",
           "subdiv_refine", "default_settings", "part_info", "write_lightmap_exr", "write_heat_map_exr",
           "read_lightmap_exr"]

_C = _lib.lib
_OK = 0
_CANCELLED = 5
_LIGHT_TYPES = {"POINT": 0, "SPOT": 1, "SUN": 2, "AREA_RECT": 3, "AREA_DISK": 4, "PORTAL": 5}


class PhotonlmError(Exception):
    """A photonlm call failed. .status is the C status name, .message the engine's message."""

    def __init__(self, message, status="PLM_ERROR_INTERNAL"):
        super().__init__(message)
        self.message = message
        self.status = status

    def __str__(self):
        return "%s (%s)" % (self.message, self.status)


class BakeCancelled(PhotonlmError):
    """The bake was cancelled by the progress callback."""


def _check(status):
    """Raise the matching exception for a non-OK status; reads plm_last_error on this thread."""
    if status == _OK:
        return
    message = (_C.plm_last_error() or b"").decode("utf-8", "replace")
    name = (_C.plm_status_string(status) or b"PLM_ERROR_%d" % status).decode("ascii", "replace")
    raise (BakeCancelled if status == _CANCELLED else PhotonlmError)(message or name, name)


def version():
    """Version of the loaded native library, "major.minor.patch"."""
    return _C.plm_version().decode("ascii")


def _uint(x, what, bits=32):
    try:
        v = operator.index(x)
    except TypeError:
        v = int(x)
        if v != x:
            raise ValueError("%s must be an integer, got %r" % (what, x)) from None
    if not 0 <= v < (1 << bits):
        raise ValueError("%s must be in [0, 2^%d), got %d" % (what, bits, v))
    return v


def _choice(x, what, names):
    """The index of x in names (the C enum's order)."""
    if x not in names:
        raise ValueError("%s must be one of %s, got %r" % (what, ", ".join(map(repr, names)), x))
    return names.index(x)


def _rgb(x, what):
    a = np.asarray(x, dtype=np.float32)
    if a.ndim == 0:
        a = np.repeat(a, 3)
    if a.shape != (3,):
        raise ValueError("%s must be 3 floats (RGB) or one float, got shape %s" % (what, a.shape))
    return np.ascontiguousarray(a)


def _indices(x, what):
    """Any integer array -> contiguous uint32 (no copy if it already is); negatives are an error."""
    a = np.asarray(x)
    if a.size == 0:
        return np.ascontiguousarray(a, dtype=np.uint32)
    if a.dtype.kind not in "iu":
        raise ValueError("%s must be an integer array, got dtype %s" % (what, a.dtype))
    if a.dtype.kind == "i" and a.min() < 0:
        bad = np.argwhere(a < 0)[0]
        raise ValueError("%s must not be negative: %s[%s] = %d"
                         % (what, what, ", ".join(map(str, bad)), a[tuple(bad)]))
    if a.dtype.itemsize > 4 and a.max() > 0xFFFFFFFF:
        raise ValueError("%s has values above 2^32 - 1" % what)
    return np.ascontiguousarray(a, dtype=np.uint32)


def _resolution(resolution):
    """(width, height) of a lightmap given as n or (width, height)."""
    if np.ndim(resolution) == 0:
        return (_uint(resolution, "resolution"),) * 2
    if len(resolution) != 2:
        raise ValueError("resolution must be n or (width, height), got %r" % (resolution,))
    return tuple(_uint(r, "resolution") for r in resolution)


def _ptr(a, ctype):
    return None if a is None else a.ctypes.data_as(ctypes.POINTER(ctype))


def _lobe(kind, color, roughness, ior, abbe, weight):
    """A filled plm_lobe: the kind's defaults (plm_lobe_default), then the given values."""
    lobe = _lib.plm_lobe()
    _C.plm_lobe_default(ctypes.byref(lobe), kind)
    lobe.color[:] = [float(c) for c in _rgb(color, "lobe color")]
    lobe.roughness = float(roughness)
    if ior is not None:
        lobe.ior = float(ior)
    lobe.abbe = float(abbe)
    lobe.weight = float(weight)
    return lobe


def _name(name):
    return None if name is None else str(name).encode("utf-8")


def _lsystem_settings(depth, seed, matrix, step, angle, width, materials=None, ol_level=0, ol_resolution=0):
    """A filled plm_lsystem_settings; the returned tuple keeps the materials array alive."""
    s = _lib.plm_lsystem_settings()
    _C.plm_lsystem_settings_default(ctypes.byref(s))
    s.depth = _uint(depth, "depth")
    s.seed = _uint(seed, "seed")
    if matrix is not None:
        m = np.asarray(matrix, np.float64)
        if m.shape not in ((3, 4), (4, 4)):
            raise ValueError("matrix must be 3x4 or 4x4, got shape %s" % (m.shape,))
        for k, v in enumerate(m[:3].ravel()):
            s.matrix[k] = float(v)
    s.step, s.angle, s.width = float(step), float(angle), float(width)
    mats = None
    if materials is not None:
        mats = _indices(np.atleast_1d(materials), "materials")
        if mats.size:
            s.materials = _ptr(mats, ctypes.c_uint32)
            s.material_count = mats.size
    s.ol_level = _uint(ol_level, "ol_level")
    s.ol_resolution = _uint(ol_resolution, "ol_resolution")
    return s, mats


# plm_csg_shape codes of the primitives lsystem_flatten returns.
LSYSTEM_SHAPES = {0: "SPHERE", 1: "BOX", 2: "CYLINDER", 3: "CONE"}


def _cage(name, positions, face_sizes, face_indices, lightmap_uv, crease_edges, crease_weights):
    """Checked, contiguous arrays of a subdivision cage (see Scene.add_subdiv_mesh)."""
    pos = np.ascontiguousarray(positions, dtype=np.float32)
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise ValueError("positions of mesh %r must have shape (V, 3), got %s" % (name, pos.shape))
    sizes = _indices(face_sizes, "face_sizes")
    if sizes.ndim != 1:
        raise ValueError("face_sizes of mesh %r must have shape (F,), got %s" % (name, sizes.shape))
    corners = int(sizes.sum(dtype=np.int64))
    fidx = _indices(face_indices, "face_indices").reshape(-1)
    if fidx.shape != (corners,):
        raise ValueError("face_indices of mesh %r must hold sum(face_sizes) = %d indices, got %d"
                         % (name, corners, fidx.size))
    uv = None
    if lightmap_uv is not None:
        uv = np.ascontiguousarray(lightmap_uv, dtype=np.float32)
        if uv.shape != (corners, 2):
            raise ValueError("lightmap_uv of mesh %r must have shape (sum(face_sizes), 2) = (%d, 2), got %s"
                             % (name, corners, uv.shape))
    edges = weights = None
    count = 0
    if crease_edges is not None or crease_weights is not None:
        if crease_edges is None or crease_weights is None:
            raise ValueError("crease_edges and crease_weights of mesh %r go together" % (name,))
        edges = _indices(crease_edges, "crease_edges")
        weights = np.ascontiguousarray(crease_weights, dtype=np.float32)
        if edges.ndim != 2 or edges.shape[1] != 2 or weights.shape != (edges.shape[0],):
            raise ValueError("crease_edges of mesh %r must have shape (C, 2) and crease_weights (C,), "
                             "got %s and %s" % (name, edges.shape, weights.shape))
        count = edges.shape[0]
    return pos, sizes, fidx, uv, edges, weights, count


def subdiv_refine(positions, face_sizes, face_indices, level, lightmap_uv=None, crease_edges=None,
                  crease_weights=None):
    """The engine's refinement of a cage (as Scene.add_subdiv_mesh makes it): positions (V, 3) f32,
    triangles (T, 3) u32 and, with lightmap_uv, the UV per triangle corner (T, 3, 2) f32 (else None)."""
    pos, sizes, fidx, uv, edges, weights, count = _cage("cage", positions, face_sizes, face_indices,
                                                        lightmap_uv, crease_edges, crease_weights)
    nv, nt = ctypes.c_uint32(), ctypes.c_uint32()
    args = [_ptr(pos, ctypes.c_float), _uint(pos.shape[0], "vertex count"), _ptr(sizes, ctypes.c_uint32),
            _uint(sizes.shape[0], "face count"), _ptr(fidx, ctypes.c_uint32), _ptr(uv, ctypes.c_float),
            _ptr(edges, ctypes.c_uint32), _ptr(weights, ctypes.c_float), _uint(count, "crease count"),
            _uint(level, "level")]
    _check(_C.plm_subdiv_refine(*args, None, 0, None, None, 0, ctypes.byref(nv), ctypes.byref(nt)))
    out_pos = np.empty((nv.value, 3), np.float32)
    out_tri = np.empty((nt.value, 3), np.uint32)
    out_uv = np.empty((nt.value, 3, 2), np.float32) if uv is not None else None
    _check(_C.plm_subdiv_refine(*args, _ptr(out_pos, ctypes.c_float), nv.value, _ptr(out_tri, ctypes.c_uint32),
                                _ptr(out_uv, ctypes.c_float), nt.value, ctypes.byref(nv), ctypes.byref(nt)))
    return out_pos, out_tri, out_uv


def lsystem_flatten(rules, depth=0, seed=0, max_primitives=100000, step=-1, angle=-1, width=-1, matrix=None):
    """Flatten an L-system for a viewport preview.

    Returns (shapes, matrices, materials, truncated): shapes (N,) uint32 plm_csg_shape codes
    (LSYSTEM_SHAPES: 0 SPHERE, 1 BOX, 2 CYLINDER, 3 CONE); matrices (N, 3, 4) float64 mapping the
    canonical CSG shape (Scene.add_csg) to world space, the placement `matrix` included;
    materials (N,) uint32 turtle material indices; truncated: max_primitives was reached.
    depth 0 and step/angle/width < 0 take the rules' values."""
    settings, _ = _lsystem_settings(depth, seed, matrix, step, angle, width)
    text = str(rules).encode("utf-8")
    cap = _uint(max_primitives, "max_primitives", 64)
    count, truncated = ctypes.c_uint64(), ctypes.c_int()
    _check(_C.plm_lsystem_flatten(text, ctypes.byref(settings), cap, None, None, None, ctypes.byref(count),
                                  ctypes.byref(truncated)))
    n = count.value
    shapes = np.zeros(n, np.uint32)
    matrices = np.zeros((n, 3, 4), np.float64)
    materials = np.zeros(n, np.uint32)
    if n:
        _check(_C.plm_lsystem_flatten(text, ctypes.byref(settings), n, _ptr(shapes, ctypes.c_uint32),
                                      _ptr(matrices, ctypes.c_double), _ptr(materials, ctypes.c_uint32),
                                      ctypes.byref(count), None))
    return shapes, matrices, materials, bool(truncated.value)


class _Handle:
    _release = None

    def __init__(self, handle):
        self._handle = handle

    @property
    def _h(self):
        if not self._handle:
            raise ValueError("%s is closed" % type(self).__name__)
        return self._handle

    def close(self):
        """Release the native object; further use raises ValueError. Safe to call twice."""
        handle, self._handle = getattr(self, "_handle", None), None
        if handle:
            getattr(_C, self._release)(handle)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        try:
            self.close()
        except Exception:
            pass


class Scene(_Handle):
    """A scene to bake: materials, world-space triangle meshes, lights and a world colour."""
    _release = "plm_scene_release"

    CONVENTIONS = {"cycles-3.4": 0, "cycles-4": 1}

    def __init__(self, conventions="cycles-3.4"):
        """conventions: whose Cycles the lights follow (set_conventions)."""
        handle = _lib.ScenePtr()
        _check(_C.plm_scene_create(ctypes.byref(handle)))
        super().__init__(handle)
        if conventions != "cycles-3.4":
            self.set_conventions(conventions)

    def set_conventions(self, conventions):
        """Whose Cycles the scene's lights follow (docs/design/cycles-versions.md "Cycles versions"): "cycles-3.4"
        (Blender 3.x, the default: area light radiance P / (4 A), spot intensity with a cos factor
        in the cone) or "cycles-4" (Blender 4.0 to 5.2: area radiance P / (pi A), spot intensity
        the smoothstep alone). Point and sun lights, emission and the world do not change.
        photonlm_blender.compat.cycles_conventions() gives the name for the running Blender."""
        if conventions not in self.CONVENTIONS:
            raise ValueError("conventions must be one of %s, got %r" % (sorted(self.CONVENTIONS), conventions))
        _check(_C.plm_scene_set_conventions(self._h, self.CONVENTIONS[conventions]))

    @property
    def conventions(self):
        """The conventions' name ("cycles-3.4" or "cycles-4")."""
        out = ctypes.c_int32()
        _check(_C.plm_scene_get_conventions(self._h, ctypes.byref(out)))
        return {v: k for k, v in self.CONVENTIONS.items()}[out.value]

    def add_material(self, albedo, emission=(0.0, 0.0, 0.0), name=None):
        """Add a Lambertian material; albedo in [0, 1] RGB, emission is radiance (both sides).
        Returns the material id (the first one is 0, used by meshes without material_ids)."""
        albedo, emission = _rgb(albedo, "albedo"), _rgb(emission, "emission")
        out = ctypes.c_uint32()
        _check(_C.plm_scene_add_material(self._h, _name(name), _ptr(albedo, ctypes.c_float),
                                         _ptr(emission, ctypes.c_float), ctypes.byref(out)))
        return out.value

    def add_mesh(self, name, positions, triangles, lightmap_uv=None, material_ids=None, resolution=0):
        """Add a world-space triangle mesh and return its id.

        positions (V, 3) float32; triangles (T, 3) vertex indices (any integer dtype);
        lightmap_uv (T, 3, 2) or (3T, 2) float32, one (u, v) per triangle corner;
        material_ids (T,) or None (material 0); resolution n (n x n texels) or (width, height),
        0 = geometry only (lightmap_uv may then be None).
        """
        pos = np.ascontiguousarray(positions, dtype=np.float32)
        if pos.ndim != 2 or pos.shape[1] != 3:
            raise ValueError("positions of mesh %r must have shape (V, 3), got %s" % (name, pos.shape))
        tri = _indices(triangles, "triangles")
        if tri.ndim != 2 or tri.shape[1] != 3:
            raise ValueError("triangles of mesh %r must have shape (T, 3), got %s" % (name, tri.shape))
        t = tri.shape[0]
        uv = None
        if lightmap_uv is not None:
            uv = np.ascontiguousarray(lightmap_uv, dtype=np.float32)
            if uv.shape not in ((t, 3, 2), (3 * t, 2)):
                raise ValueError("lightmap_uv of mesh %r must have shape (T, 3, 2) or (3T, 2) with "
                                 "T = %d triangles, got %s" % (name, t, uv.shape))
        mats = None
        if material_ids is not None:
            mats = _indices(material_ids, "material_ids")
            if mats.shape != (t,):
                raise ValueError("material_ids of mesh %r must have shape (T,) with T = %d triangles, "
                                 "got %s" % (name, t, mats.shape))
        width, height = _resolution(resolution)
        out = ctypes.c_uint32()
        _check(_C.plm_scene_add_mesh(
            self._h, _name(name), _ptr(pos, ctypes.c_float), _uint(pos.shape[0], "vertex count"),
            _ptr(tri, ctypes.c_uint32), _uint(t, "triangle count"), _ptr(uv, ctypes.c_float),
            _ptr(mats, ctypes.c_uint32), width, height, ctypes.byref(out)))
        self.__dict__.setdefault("_mesh_triangles", {})[out.value] = t
        return out.value

    def add_subdiv_mesh(self, name, positions, face_sizes, face_indices, level, lightmap_uv=None,
                        material_ids=None, crease_edges=None, crease_weights=None, resolution=0):
        """Add a Catmull-Clark subdivision surface given by its world-space polygon cage; the
        engine refines it with OpenSubdiv as Blender's Subdivision Surface modifier does with its
        defaults. Returns an ordinary mesh id.

        positions (V, 3) float32; face_sizes (F,) corner counts (>= 3); face_indices (sum(face_sizes),)
        vertex indices, face after face (Blender's polygon loops); level 1..10;
        lightmap_uv (sum(face_sizes), 2) one (u, v) per face corner (Blender's loops);
        material_ids (F,) per face or None; crease_edges (C, 2) vertex pairs, each a cage edge,
        with crease_weights (C,) Blender creases in [0, 1]; resolution as for add_mesh.
        """
        pos, sizes, fidx, uv, edges, weights, count = _cage(name, positions, face_sizes, face_indices,
                                                            lightmap_uv, crease_edges, crease_weights)
        corners = fidx.shape[0]
        mats = None
        if material_ids is not None:
            mats = _indices(material_ids, "material_ids")
            if mats.shape != sizes.shape:
                raise ValueError("material_ids of mesh %r must have shape (F,) = %s, got %s"
                                 % (name, sizes.shape, mats.shape))
        width, height = _resolution(resolution)
        level = _uint(level, "level")
        out = ctypes.c_uint32()
        _check(_C.plm_scene_add_subdiv_mesh(
            self._h, _name(name), _ptr(pos, ctypes.c_float), _uint(pos.shape[0], "vertex count"),
            _ptr(sizes, ctypes.c_uint32), _uint(sizes.shape[0], "face count"), _ptr(fidx, ctypes.c_uint32),
            _ptr(uv, ctypes.c_float), _ptr(mats, ctypes.c_uint32), _ptr(edges, ctypes.c_uint32),
            _ptr(weights, ctypes.c_float), _uint(count, "crease count"), level, width, height,
            ctypes.byref(out)))
        self.__dict__.setdefault("_mesh_triangles", {})[out.value] = 2 * corners * 4 ** (level - 1)
        return out.value

    def refine_subdiv_meshes(self, threads=0):
        """Refine every cage add_subdiv_mesh added since the last call, in parallel on `threads`
        threads (0: all cores); bake() does it itself. add_subdiv_mesh checks each cage (its errors
        name the mesh); this fails only for want of memory, naming the mesh."""
        _check(_C.plm_scene_refine_subdiv_meshes(self._h, _uint(threads, "threads")))

    LOBE_KINDS = {"glossy": 0, "fresnel": 1, "glass": 2, "refraction": 3, "transparent": 4, "specular": 5}

    def add_material_lobe(self, material, kind, color, roughness=0.0, ior=None, abbe=0.0, weight=1.0):
        """Add a specular lobe to a material (at most 8; docs/design/materials.md "Materials"). kind:
        "glossy" (GGX reflection of `color` at every angle), "fresnel" (GGX reflection rising from
        `color` = F0 at normal incidence to `weight` at grazing, as a dielectric of `ior`),
        "glass" (Fresnel reflection and refraction, tinted), "refraction" (refraction only),
        "transparent" (straight through), "specular" (Blender 4's Principled BSDF specular layer:
        as "fresnel" with Cycles 4's multiple-scattering GGX, and the diffuse albedo under it scaled
        by one minus its directional albedo). color RGB in [0, 1]; weight in [0, 1] multiplies the
        lobe (mix factors); roughness is Blender's (GGX alpha = roughness^2); ior None takes the
        kind's default (1.45 for glass and refraction, else 1.5); abbe > 0 gives glass and
        refraction dispersion (Abbe number). Per channel albedo + weight x color over the lobes
        other than "fresnel" and "specular" must not exceed 1."""
        if kind not in self.LOBE_KINDS:
            raise ValueError("lobe kind must be one of %s, got %r" % (sorted(self.LOBE_KINDS), kind))
        lobe = _lobe(self.LOBE_KINDS[kind], color, roughness, ior, abbe, weight)
        _check(_C.plm_scene_add_material_lobe(self._h, _uint(material, "material"), ctypes.byref(lobe)))

    DIFFUSE_MODELS = {"lambert": 0, "burley": 1}

    def set_material_diffuse(self, material, model, roughness=0.0):
        """Set a material's diffuse model: "lambert" (the default) or "burley" (Blender 3.x's
        Principled BSDF diffuse, Cycles 3.4's Burley law with `roughness` in [0, 1], the node's
        Roughness): its surface scatters light by that law and its lightmap holds what Cycles 3.4
        bakes for it (light arriving at grazing angles weighted as Burley weighs it toward the
        normal). docs/design/cycles-versions.md "Cycles versions"."""
        if model not in self.DIFFUSE_MODELS:
            raise ValueError("diffuse model must be one of %s, got %r" % (sorted(self.DIFFUSE_MODELS), model))
        _check(_C.plm_scene_set_material_diffuse(self._h, _uint(material, "material"), self.DIFFUSE_MODELS[model],
                                                 float(roughness)))

    TEXTURE_SLOTS = {"albedo": 0, "emission": 1}
    TEXTURE_COLORSPACES = {"auto": 0, "linear": 1, "srgb": 2}

    def set_material_texture(self, material, slot, path, colorspace="auto"):
        """Give a material an image texture. slot "albedo" (albedo = image x the material's albedo)
        or "emission" (radiance = image x the material's emission); path None or "" removes it.
        colorspace "auto" (8/16-bit images are sRGB, float images linear), "linear" or "srgb".
        Meshes need texture UVs (set_mesh_texture_uv); without them the image's mean is used."""
        if slot not in self.TEXTURE_SLOTS:
            raise ValueError("texture slot must be one of %s, got %r" % (sorted(self.TEXTURE_SLOTS), slot))
        if colorspace not in self.TEXTURE_COLORSPACES:
            raise ValueError("colorspace must be one of %s, got %r" % (sorted(self.TEXTURE_COLORSPACES), colorspace))
        encoded = os.fsencode(os.fspath(path)) if path else None
        _check(_C.plm_scene_set_material_texture(self._h, _uint(material, "material"), self.TEXTURE_SLOTS[slot],
                                                 encoded, self.TEXTURE_COLORSPACES[colorspace]))

    def set_mesh_texture_uv(self, mesh, uv):
        """Set a mesh's texture UVs: (T, 3, 2) or (3T, 2) float32, one (u, v) per triangle corner
        ((0, 0) = the image's bottom-left corner, as in Blender); None removes them."""
        mesh = self._mesh(mesh)
        t = self._mesh_triangles[mesh]
        if uv is None:
            _check(_C.plm_scene_set_mesh_texture_uv(self._h, mesh, None))
            return
        arr = np.ascontiguousarray(uv, dtype=np.float32)
        if arr.shape not in ((t, 3, 2), (3 * t, 2)):
            raise ValueError("texture uv of mesh %d must have shape (T, 3, 2) or (3T, 2) with T = %d triangles, "
                             "got %s" % (mesh, t, arr.shape))
        _check(_C.plm_scene_set_mesh_texture_uv(self._h, mesh, _ptr(arr, ctypes.c_float)))

    def set_mesh_normals(self, mesh, normals):
        """Set a mesh's shading normals (smooth shading, custom split normals): (T, 3, 3) or (3T, 3)
        float32, one normal per triangle corner (any length); a (0, 0, 0) corner shades with its
        triangle's geometric normal (a flat face). None removes them."""
        mesh = self._mesh(mesh)
        if normals is None:
            _check(_C.plm_scene_set_mesh_normals(self._h, mesh, None))
            return
        t = self._mesh_triangles[mesh]
        arr = np.ascontiguousarray(normals, dtype=np.float32)
        if arr.shape not in ((t, 3, 3), (3 * t, 3)):
            raise ValueError("normals of mesh %d must have shape (T, 3, 3) or (3T, 3) with T = %d triangles, "
                             "got %s" % (mesh, t, arr.shape))
        _check(_C.plm_scene_set_mesh_normals(self._h, mesh, _ptr(arr, ctypes.c_float)))

    def set_mesh_smooth(self, mesh, smooth=True):
        """Shade a mesh smooth with normals the engine computes (angle-weighted vertex normals, as
        Blender's; for a subdivision mesh those of the refined mesh), or flat (smooth=False)."""
        _check(_C.plm_scene_set_mesh_smooth(self._h, self._mesh(mesh), 1 if smooth else 0))

    def _mesh(self, mesh):
        mesh = _uint(mesh, "mesh")
        if mesh not in self.__dict__.get("_mesh_triangles", {}):
            raise ValueError("mesh %d does not exist" % mesh)
        return mesh

    def add_light(self, type, *, name=None, color=None, power=None, matrix=None, radius=None,
                  angle=None, size=None, size_y=None, spot_size=None, spot_blend=None):
        """Add a Blender-style light and return its id.

        type: 'POINT', 'SPOT', 'SUN', 'AREA_RECT', 'AREA_DISK' or 'PORTAL' (a rectangle in an
        opening, local -Z into the interior: sun and sky are sampled through it). Fields left None keep
        Blender's defaults (plm_light_default). power is W (sun: irradiance W/m^2); matrix is
        the 4x4 object-to-world matrix (numpy or mathutils.Matrix); lights shine along local -Z.
        size_y defaults to size (square / circle) when only size is given.
        """
        try:
            kind = _LIGHT_TYPES[str(type).upper()]
        except KeyError:
            raise ValueError("light type must be one of %s, got %r" % (", ".join(_LIGHT_TYPES), type)) from None
        light = _lib.plm_light()
        _C.plm_light_default(ctypes.byref(light), kind)
        if color is not None:
            light.color = (ctypes.c_float * 3)(*_rgb(color, "color").tolist())
        if matrix is not None:
            m = np.array(matrix, dtype=np.float32)
            if m.shape != (4, 4):
                raise ValueError("matrix must be 4x4, got shape %s" % (m.shape,))
            light.matrix = (ctypes.c_float * 16)(*m.ravel().tolist())
        if size is not None and size_y is None:
            size_y = size
        for field, value in (("power", power), ("radius", radius), ("angle", angle), ("size_x", size),
                             ("size_y", size_y), ("spot_size", spot_size), ("spot_blend", spot_blend)):
            if value is not None:
                setattr(light, field, float(value))
        out = ctypes.c_uint32()
        _check(_C.plm_scene_add_light(self._h, _name(name), ctypes.byref(light), ctypes.byref(out)))
        return out.value

    CSG_SHAPES = ("SPHERE", "BOX", "CYLINDER", "CONE", "TORUS", "PARABOLOID", "HALF_SPACE")
    CSG_OPS = ("UNION", "INTERSECTION", "DIFFERENCE")

    def add_csg(self, name, primitives, tree):
        """Add a CSG solid traced exactly; returns its id.

        primitives: list of dicts {shape: one of CSG_SHAPES, matrix: 3x4 or 4x4 local -> world (the
        shape's canonical form is Blender's default primitive: sphere radius 1, box [-1, 1]^3,
        cylinder radius 1 z in [-1, 1], cone base radius 1 at z = -1 apex at z = +1, torus
        major/minor radius, paraboloid z = x^2 + y^2 up to z = 1, half-space z <= 0), material: id,
        major_radius / minor_radius (torus)}.
        tree: a primitive index (a leaf) or a tuple (op, child, child, ...) with op in CSG_OPS;
        DIFFERENCE = first child minus the others.
        """
        prims = _lib.sized_array(_lib.plm_csg_primitive, max(1, len(primitives)))
        for i, p in enumerate(primitives):
            shape = _choice(p.get("shape"), "primitive %d shape" % i, self.CSG_SHAPES)
            m = np.asarray(p.get("matrix", np.eye(4)), np.float64)
            if m.shape not in ((3, 4), (4, 4)):
                raise ValueError("primitive %d: matrix must be 3x4 or 4x4, got %s" % (i, m.shape))
            prims[i].shape = shape
            prims[i].material = _uint(p.get("material", 0), "primitive %d material" % i)
            for k, v in enumerate(m[:3].ravel()):
                prims[i].matrix[k] = float(v)
            prims[i].major_radius = float(p.get("major_radius", 1.0))
            prims[i].minor_radius = float(p.get("minor_radius", 0.25))
        nodes, children = [], []

        def add(node):  # returns the node index; children are listed contiguously
            if isinstance(node, (tuple, list)):
                op = _choice(node[0], "tree operator", self.CSG_OPS)
                index = len(nodes)
                nodes.append([op, 0, len(node) - 1])
                kids = [add(child) for child in node[1:]]
                nodes[index][1] = len(children)
                children.extend(kids)
                return index
            nodes.append([3, _uint(node, "tree leaf"), 0])
            return len(nodes) - 1
        root = add(tree)
        cnodes = (_lib.plm_csg_node * len(nodes))(*[_lib.plm_csg_node(*n) for n in nodes])
        ckids = (ctypes.c_uint32 * max(1, len(children)))(*children)
        out = ctypes.c_uint32()
        _check(_C.plm_scene_add_csg(self._h, _name(name), prims, len(primitives), cnodes, len(nodes), ckids,
                                    len(children), root, ctypes.byref(out)))
        return out.value

    def set_csg_carrier(self, csg, mesh):
        """Make a mesh with a lightmap the carrier of a CSG solid: the mesh is not traced (the exact
        solid stands in for it) and its lightmap shows the solid's light."""
        _check(_C.plm_scene_set_csg_carrier(self._h, _uint(csg, "csg"), _uint(mesh, "mesh")))

    def add_ol_group(self, name=None, resolution=0):
        """Add an orientation-lightmap group and return its id (0, 1, ...).

        Its meshes share one map over surface normals (resolution x resolution bins of an
        equal-area octahedral map; 0 = automatic, 16) instead of per-texel lightmaps."""
        out = ctypes.c_uint32()
        _check(_C.plm_scene_add_ol_group(self._h, _name(name), _uint(resolution, "resolution"),
                                         ctypes.byref(out)))
        return out.value

    def set_ol_group_backup(self, group, backup=True):
        """Make an OL group a backup: its lightmapped meshes keep their own texels, and each texel's
        indirect light is combined with the OL at its normal by inverse variance (noisy texels lean
        on the OL; the OL's bias against the texels is estimated and counted)."""
        _check(_C.plm_scene_set_ol_group_backup(self._h, _uint(group, "group"), 1 if backup else 0))

    def set_ol_group_limit_area(self, group, limit_area=True):
        """Take the per-bin areas of the group's subdivision meshes from their limit surface instead
        of their refined triangles (photons still hit the triangles: the OL then describes the limit
        surface and reads lower by A_triangles / A_limit, 12 % for a cube cage at level 1)."""
        _check(_C.plm_scene_set_ol_group_limit_area(self._h, _uint(group, "group"), 1 if limit_area else 0))

    def set_mesh_ol_group(self, mesh, group):
        """Put a mesh into an OL group. A mesh with a lightmap gets it resolved from the OL (each
        texel shows the OL at the texel's normal); one without needs no UVs."""
        _check(_C.plm_scene_set_mesh_ol_group(self._h, _uint(mesh, "mesh"), _uint(group, "group")))

    def add_light_group(self, name):
        """Declare a light group and return its id (1, 2, ...; 0 is the default group).

        One bake then gives each lightmap one layer per group (Result.layers, Result.lightmap_layer),
        from the same photons and direct samples; the layers add up to the lightmap. name: letters,
        digits, '_' and '-' (it names the layer's files), not "default"."""
        out = ctypes.c_uint32()
        _check(_C.plm_scene_add_light_group(self._h, _name(name), ctypes.byref(out)))
        return out.value

    def set_light_group(self, group, *, light=None, mesh=None, world=False):
        """Put a light, a mesh's emission or the world (world=True) into a light group (0: the
        default group). Give exactly one of light, mesh and world."""
        if (light is not None) + (mesh is not None) + bool(world) != 1:
            raise ValueError("set_light_group: give exactly one of light=, mesh= and world=True")
        group = _uint(group, "group")
        if light is not None:
            _check(_C.plm_scene_set_light_group(self._h, _uint(light, "light"), group))
        elif mesh is not None:
            _check(_C.plm_scene_set_mesh_light_group(self._h, _uint(mesh, "mesh"), group))
        else:
            _check(_C.plm_scene_set_world_light_group(self._h, group))

    def add_lsystem(self, name, rules, depth=0, seed=0, matrix=None, step=-1, angle=-1, width=-1,
                    materials=None, ol_level=0, ol_resolution=0):
        """Add an L-system object (a plant traced as a scene graph, lit through orientation
        lightmaps) and return its id (0, 1, ...).

        rules: the L-system text (axiom, productions, depth, step, angle, width). depth 0 and
        step/angle/width < 0 take the rules' values. matrix: 3x4 or 4x4 placement local -> world
        (rotation times a uniform scale, plus translation). materials: scene material id per turtle
        material index (None: material 0). ol_level: one stub OL per node instance this many levels
        below the root (0 = one OL for the whole object); ol_resolution: bins per side (0 = 16).
        Parse errors name the line and column."""
        settings, mats = _lsystem_settings(depth, seed, matrix, step, angle, width, materials, ol_level,
                                           ol_resolution)
        out = ctypes.c_uint32()
        _check(_C.plm_scene_add_lsystem(self._h, _name(name), str(rules).encode("utf-8"), ctypes.byref(settings),
                                        ctypes.byref(out)))
        del mats
        return out.value

    def set_world(self, radiance):
        """Uniform world radiance (RGB, Cycles background colour x strength) over the whole sphere.
        Replaces an environment map."""
        rad = _rgb(radiance, "radiance")
        _check(_C.plm_scene_set_world(self._h, _ptr(rad, ctypes.c_float)))

    def set_world_map(self, rgb, rotation=None, strength=1.0):
        """An environment map as the world (Cycles' Environment Texture in the Background):
        rgb (H, W, 3) float32 linear radiance, the top row (+Z) first, in Blender's
        equirectangular mapping (the image's centre looks along +X, u = 0.5 - atan2(y, x) / 2 pi);
        radiance = rgb x strength. rotation: 3x3 (or 9 floats) taking the map's frame into the
        world (None = identity); for Blender's Mapping node (Point or Vector type) of rotation
        matrix M it is M transposed. Replaces the uniform world. Errors name the row and column
        of a non-finite or negative pixel."""
        a = np.ascontiguousarray(rgb, dtype=np.float32)
        if a.ndim != 3 or a.shape[2] != 3:
            raise ValueError("world map rgb must have shape (H, W, 3), got %s" % (a.shape,))
        rot = self._rotation(rotation)
        _check(_C.plm_scene_set_world_map(self._h, _ptr(a, ctypes.c_float), _uint(a.shape[1], "map width"),
                                          _uint(a.shape[0], "map height"), _ptr(rot, ctypes.c_float),
                                          float(strength)))

    def set_world_map_file(self, path, rotation=None, strength=1.0):
        """An environment map read from an image file (HDR, EXR, PFM, PNG, JPEG...: the types textures take;
        integer images are sRGB-decoded, float images linear) when called; as set_world_map."""
        rot = self._rotation(rotation)
        _check(_C.plm_scene_set_world_map_file(self._h, os.fsencode(os.fspath(path)), _ptr(rot, ctypes.c_float),
                                               float(strength)))

    @staticmethod
    def _rotation(rotation):
        if rotation is None:
            return None
        r = np.ascontiguousarray(rotation, dtype=np.float32).reshape(-1)
        if r.shape != (9,):
            raise ValueError("rotation must be a 3x3 matrix (9 floats), got %d values" % r.size)
        return r

    def bake(self, photons=None, max_bounces=None, seed=None, threads=None, dilation=None, progress=None,
             target_error=None, time_budget=None, direct_samples=None, filter_radius=None,
             texel_value=None, sampler=None, directional=None, preview=None, preview_interval=3.0):
        """Bake all lightmaps and return a Result. The GIL is released while the engine runs.
        A setting left None takes the engine's default (default_settings()).

        Two passes: direct light from direct_samples shadow-ray points per texel (0 = photons
        carry direct light too), indirect light from photons. With target_error (relative RMS
        error, e.g. 0.02) or time_budget (seconds) set, photons are traced until the estimated
        error reaches the target or the time is spent; photons is then the cap (0 = none).
        filter_radius: largest radius in texels over which a texel's photon estimate pools
        neighbours on the same surface until it holds enough hits (0 = each texel alone).
        texel_value: "CYCLES" (direct light averaged over the texel's central 0.5 x 0.5 square,
        what Cycles 3.4 bakes converge to) or "AREA" (over the whole texel: smoother edges). sampler: "DEFAULT" (Owen-scrambled
        Sobol points for the direct pass, pseudo-random photons), "RANDOM" or "SOBOL" (everywhere).
        directional: True to keep each texel's light's direction too (SH L1: Result.lightmap_sh).

        progress: optional callable(fraction, stage) called from this thread every few tenths
        of a second; returning False cancels (BakeCancelled). An exception raised in it cancels
        the bake and is re-raised here (so is Ctrl-C).

        preview: optional callable(Preview) called from this thread while the bake runs, once the
        direct pass's first round is done and then at most every preview_interval seconds (between
        direct rounds and groups of photons; 0 = never), with the lightmaps at that state; it copies what it wants (Preview.lightmap)
        and returns quickly. Returning False cancels, an exception cancels and is re-raised.
        Previews change nothing: the result equals that of a bake without them.
        """
        settings = _bake_settings(photons=photons, max_bounces=max_bounces, seed=seed, threads=threads,
                                  dilation=dilation, target_error=target_error, time_budget=time_budget,
                                  direct_samples=direct_samples, filter_radius=filter_radius,
                                  texel_value=texel_value, sampler=sampler, directional=directional)
        raised = []
        callback = _progress_callback(progress, raised)  # referenced until plm_bake returns
        out = _lib.ResultPtr()
        if preview is None:
            status = _C.plm_bake(self._h, ctypes.byref(settings), callback, None, ctypes.byref(out))
        else:
            interval = float(preview_interval)
            if not (interval >= 0.0 and np.isfinite(interval)):
                raise ValueError("preview_interval must be a finite number of seconds >= 0, got %r"
                                 % (preview_interval,))

            def on_preview(_user_data, handle):
                p = Preview(handle)
                try:
                    keep = preview(p)
                    return 0 if keep is not None and not keep else 1
                except BaseException as e:  # noqa: BLE001 -- cancel, re-raise after the bake
                    raised.append(e)
                    return 0
                finally:
                    p._h = None  # the handle dies with the call

            preview_callback = _lib.preview_fn(on_preview)
            status = _C.plm_bake_with_preview(self._h, ctypes.byref(settings), callback, preview_callback,
                                              interval, None, ctypes.byref(out))
        return _result(status, out, raised)

    def bake_shard(self, shard, shard_count, part_path, scene_path=None, progress=None, **settings):
        """Bake shard `shard` (0-based) of `shard_count`: trace its share of the photons and write
        their sums to part_path (written whole or not at all), for merge() on this or another
        machine (docs/farm.md). settings as for bake(); a sharded bake needs a photon count (no
        target_error or time_budget) and a scene without OL groups or L-system objects. scene_path
        is recorded in the part (what `photonlm merge` reads the scene from when not given one)."""
        s = _bake_settings(**settings)
        raised = []
        callback = _progress_callback(progress, raised)
        status = _C.plm_bake_shard(self._h, ctypes.byref(s), _uint(shard, "shard", 32),
                                   _uint(shard_count, "shard_count", 32),
                                   None if scene_path is None else os.fsencode(scene_path), os.fsencode(part_path),
                                   callback, None)
        if raised:
            raise raised[0]
        _check(status)

    def merge(self, part_paths, threads=None, progress=None):
        """Merge the part files of every shard of one sharded bake of this scene (each once, any
        order) into a Result: bit for bit what bake() with the same settings returns. A part that
        does not belong (another scene, seed, setting, engine version or shard count; damaged or
        truncated; a shard missing or given twice) raises PhotonlmError naming it."""
        paths = [os.fsencode(p) for p in part_paths]
        array = (ctypes.c_char_p * max(len(paths), 1))(*paths)
        raised = []
        callback = _progress_callback(progress, raised)
        out = _lib.ResultPtr()
        status = _C.plm_bake_merge(self._h, array, len(paths), _uint(threads or 0, "threads", 32), callback, None,
                                   ctypes.byref(out))
        return _result(status, out, raised)


def part_info(part_path):
    """What a part file says of itself: dict(shard=, shard_count=, scene_path=, settings=dict(...))
    (settings under bake()'s names; threads is not recorded)."""
    s = _lib.plm_bake_settings()
    shard, count = ctypes.c_uint32(), ctypes.c_uint32()
    path = ctypes.create_string_buffer(4096)
    _check(_C.plm_part_info(os.fsencode(part_path), ctypes.byref(s), ctypes.byref(shard), ctypes.byref(count),
                            path, len(path)))
    settings = _settings_dict(s)
    del settings["threads"]
    return dict(shard=shard.value, shard_count=count.value, scene_path=os.fsdecode(path.value) or None,
                settings=settings)


def _bake_settings(**given):
    """plm_bake_settings with the engine's defaults and the given values (None = default), checked."""
    settings = _lib.plm_bake_settings()
    _C.plm_bake_settings_default(ctypes.byref(settings))
    for name, value in given.items():
        if name not in _SETTING_FIELDS:
            raise TypeError("unknown bake setting %r (known: %s)" % (name, ", ".join(sorted(_SETTING_FIELDS))))
        if value is None:
            continue
        field = _SETTING_FIELDS[name]
        if name in _SETTING_CHOICES:
            value = _choice(value, name, _SETTING_CHOICES[name])
        elif name == "directional":
            if not isinstance(value, (bool, int)) or value not in (0, 1):
                raise ValueError("directional must be True or False, got %r" % (value,))
            value = int(value)
        elif name in ("target_error", "time_budget"):
            value = float(value)
            if not value >= 0.0:
                raise ValueError("%s must be a number >= 0, got %r" % (name, value))
        else:
            value = _uint(value, name, 64 if name == "photons" else 32)
        setattr(settings, field, value)
    return settings


def _progress_callback(progress, raised):
    """A progress_fn calling progress(fraction, stage); False or an exception (kept in `raised`,
    re-raised by the caller after the engine returns; Ctrl-C too) cancels."""

    def on_progress(_user_data, fraction, stage):
        try:
            if progress is not None:
                keep = progress(float(fraction), (stage or b"").decode("utf-8", "replace"))
                if keep is not None and not keep:
                    return 0
            return 1
        except BaseException as e:  # noqa: BLE001 -- cancel, re-raise after the engine returns
            raised.append(e)
            return 0

    return _lib.progress_fn(on_progress)


def _result(status, out, raised):
    """A Result from a bake's status and handle, re-raising what a callback raised."""
    if raised:
        if status == _OK:
            _C.plm_result_release(out)
        raise raised[0]
    _check(status)
    return Result(out)


class Preview:
    """The lightmaps of a running bake at one check point, handed to Scene.bake's preview
    callable. Valid only during that call (PhotonlmError afterwards)."""

    def __init__(self, handle):
        self._h = handle

    def _handle(self):
        if self._h is None:
            raise PhotonlmError("this preview is no longer valid: use it only inside the preview callback",
                                "PLM_ERROR_INVALID_ARGUMENT")
        return self._h

    @property
    def photons(self):
        """Photons traced so far (0 during the direct pass)."""
        n = ctypes.c_uint64()
        _check(_C.plm_preview_photons(self._handle(), ctypes.byref(n)))
        return n.value

    def lightmap(self, mesh_id, out=None):
        """A mesh's lightmap at this state as (h, w, 3) float32 (row 0 = bottom; dilated, seams not
        stitched), written into `out` when given (a C-contiguous float32 array of that shape); None
        for a mesh whose texels come from an OL group or a CSG solid (known only at the end)."""
        h_ = self._handle()
        mesh_id = _uint(mesh_id, "mesh_id")
        w, h = ctypes.c_uint32(), ctypes.c_uint32()
        _check(_C.plm_preview_lightmap_size(h_, mesh_id, ctypes.byref(w), ctypes.byref(h)))
        shape = (h.value, w.value, 3)
        if out is None:
            out = np.empty(shape, np.float32)
        elif out.shape != shape or out.dtype != np.float32 or not out.flags.c_contiguous:
            raise ValueError("out must be a C-contiguous float32 array of shape %s, got %s %s"
                             % (shape, out.dtype, out.shape))
        written = ctypes.c_int()
        _check(_C.plm_preview_copy_lightmap(h_, mesh_id, _ptr(out, ctypes.c_float), ctypes.byref(written)))
        return out if written.value else None


OrientationLightmap = collections.namedtuple("OrientationLightmap", "rgb error resolution area hits")
OrientationLightmap.__doc__ = """One OL group's map as float32 arrays over the octahedral square,
row = v bin, column = u bin (photonlm.h): rgb (N, N, 3) irradiance/pi; error (N, N) standard
error of the bin's mean RGB; resolution N; area (N, N) covered surface area per bin (m^2: each
triangle's area shared among the four bins a lookup at its normal interpolates, by the lookup's
bilinear weights); hits (N, N) photon hits (each in the bin of its normal)."""

Lightmap = collections.namedtuple("Lightmap", "rgb error hits coverage")
Lightmap.__doc__ = """One mesh's lightmap as float32 arrays, row 0 = bottom (v near 0):
rgb (h, w, 3) irradiance/pi; error (h, w) standard error of the texel's mean RGB;
hits (h, w) photon hits; coverage (h, w) fraction of the texel inside UV islands."""



def write_lightmap_exr(path, rgb, error=None, hits=None):
    """Write a lightmap held in arrays (row 0 = bottom) as Result.write_exr writes one: channels R, G, B,
    error, hits (None: zeros), atomically. rgb (h, w, 3); error and hits (h, w)."""
    rgb = np.ascontiguousarray(rgb, dtype=np.float32)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError("rgb must have shape (h, w, 3), got %s" % (rgb.shape,))
    h, w = rgb.shape[:2]
    planes = []
    for name, a in (("error", error), ("hits", hits)):
        if a is not None:
            a = np.ascontiguousarray(a, dtype=np.float32)
            if a.shape != (h, w):
                raise ValueError("%s must have shape %s like rgb, got %s" % (name, (h, w), a.shape))
        planes.append(a)
    _check(_C.plm_write_lightmap_exr(os.fsencode(os.fspath(path)), w, h, _ptr(rgb, ctypes.c_float),
                                     *(_ptr(a, ctypes.c_float) for a in planes)))


def write_heat_map_exr(path, values):
    """Write a (h, w) map of one value per texel (row 0 = bottom) as the R, G and B of an EXR of 16-bit
    floats, atomically. The call releases the GIL: several can run at once on threads."""
    values = np.ascontiguousarray(values, dtype=np.float32)
    if values.ndim != 2:
        raise ValueError("values must have shape (h, w), got %s" % (values.shape,))
    h, w = values.shape
    _check(_C.plm_write_heat_map_exr(os.fsencode(os.fspath(path)), w, h, _ptr(values, ctypes.c_float)))


def read_lightmap_exr(path):
    """Read a lightmap EXR (as Result.write_exr or write_lightmap_exr write it) into a Lightmap whose
    coverage is None; channels the file lacks read as 0."""
    path = os.fsencode(os.fspath(path))
    w, h = ctypes.c_uint32(), ctypes.c_uint32()
    _check(_C.plm_read_lightmap_exr(path, ctypes.byref(w), ctypes.byref(h), None, None, None))
    lm = Lightmap(np.empty((h.value, w.value, 3), np.float32), np.empty((h.value, w.value), np.float32),
                  np.empty((h.value, w.value), np.float32), None)
    _check(_C.plm_read_lightmap_exr(path, ctypes.byref(w), ctypes.byref(h), *(_ptr(a, ctypes.c_float) for a in lm[:3])))
    return lm


_STAT_KEYS = ("photons_emitted", "photon_hits", "rays_traced", "paths_truncated", "emitted_power",
              "seconds_setup", "seconds_trace", "seconds_total", "direct_samples", "seconds_direct",
              "error_estimate", "error_direct", "error_median", "error_p95", "error_above", "memory_estimate",
              "error_worst", "error_worst_mesh")


# Scene.bake's arguments -> plm_bake_settings fields, and the names of the enumerated ones.
_SETTING_FIELDS = {"photons": "photon_count", "max_bounces": "max_bounces", "seed": "seed", "threads": "thread_count",
                   "dilation": "dilation", "target_error": "target_error", "time_budget": "time_budget",
                   "direct_samples": "direct_samples", "filter_radius": "filter_radius",
                   "texel_value": "texel_value", "sampler": "sampler", "directional": "directional"}
_SETTING_CHOICES = {"texel_value": ("CYCLES", "AREA"), "sampler": ("DEFAULT", "RANDOM", "SOBOL")}


def default_settings():
    """The engine's default bake settings (plm_bake_settings_default), by the names of Scene.bake's
    arguments: the one place they are defined."""
    settings = _lib.plm_bake_settings()
    _C.plm_bake_settings_default(ctypes.byref(settings))
    return _settings_dict(settings)


def _settings_dict(settings):
    """plm_bake_settings by the names of Scene.bake's arguments."""
    out = {}
    for name, field in _SETTING_FIELDS.items():
        value = getattr(settings, field)
        out[name] = (_SETTING_CHOICES[name][value] if name in _SETTING_CHOICES
                     else bool(value) if name == "directional" else value)
    return out


class Result(_Handle):
    """The lightmaps, statistics and warnings of one bake."""
    _release = "plm_result_release"

    @property
    def stats(self):
        """dict: photons_emitted, photon_hits, rays_traced, paths_truncated, emitted_power (W),
        seconds_setup, seconds_trace, seconds_total, direct_samples, seconds_direct, error_estimate
        (relative RMS), error_direct, error_median and error_p95 (of the per-texel relative errors),
        error_above (the share of texels above twice the target error), memory_estimate (bytes),
        error_worst (the largest relative RMS error of one object, relative to its own mean: what
        target_error bounds) and error_worst_mesh (that object's mesh id, None if none)."""
        s = _lib.plm_bake_stats()
        _check(_C.plm_result_stats(self._h, ctypes.byref(s)))
        out = {k: getattr(s, k) for k in _STAT_KEYS}
        if out["error_worst_mesh"] == 0xFFFFFFFF:
            out["error_worst_mesh"] = None
        return out

    @property
    def warnings(self):
        """list of warning strings about the scene or the bake."""
        h = self._h
        return [(_C.plm_result_warning(h, i) or b"").decode("utf-8", "replace")
                for i in range(_C.plm_result_warning_count(h))]

    def lightmap_size(self, mesh_id):
        """(width, height) of a mesh's lightmap; PhotonlmError for a geometry-only mesh."""
        w, h = ctypes.c_uint32(), ctypes.c_uint32()
        _check(_C.plm_result_lightmap_size(self._h, _uint(mesh_id, "mesh_id"), ctypes.byref(w),
                                           ctypes.byref(h)))
        return w.value, h.value

    def lightmap(self, mesh_id):
        """Copy a mesh's lightmap into new numpy arrays (a Lightmap)."""
        w, h = self.lightmap_size(mesh_id)
        lm = Lightmap(np.empty((h, w, 3), np.float32), *(np.empty((h, w), np.float32) for _ in range(3)))
        _check(_C.plm_result_copy_lightmap(self._h, mesh_id, *(_ptr(a, ctypes.c_float) for a in lm)))
        return lm

    @property
    def layers(self):
        """list of the light-group layers' names, in layer order ("default" for the default group);
        empty without light groups."""
        h = self._h
        return [(_C.plm_result_layer_name(h, i) or b"").decode("utf-8", "replace")
                for i in range(_C.plm_result_layer_count(h))]

    def layer_error(self, layer):
        """A layer's estimated relative error over the covered texels (as stats' error_estimate)."""
        out = ctypes.c_double()
        _check(_C.plm_result_layer_error(self._h, self._layer(layer), ctypes.byref(out)))
        return out.value

    def _layer(self, layer):
        if isinstance(layer, str):
            names = self.layers
            if layer not in names:
                raise PhotonlmError("no light-group layer %r (the result has %s)" % (layer, names or "none"),
                                    "PLM_ERROR_INVALID_ARGUMENT")
            return names.index(layer)
        return _uint(layer, "layer")

    def lightmap_layer(self, mesh_id, layer):
        """A light-group layer (its index or name) of a mesh's lightmap: (rgb (h, w, 3), error (h, w))
        float32 arrays. The layers add up to the lightmap's rgb."""
        w, h = self.lightmap_size(mesh_id)
        rgb, err = np.empty((h, w, 3), np.float32), np.empty((h, w), np.float32)
        _check(_C.plm_result_copy_lightmap_layer(self._h, mesh_id, self._layer(layer), _ptr(rgb, ctypes.c_float),
                                                 _ptr(err, ctypes.c_float)))
        return rgb, err

    def write_layer_exr(self, mesh_id, layer, path):
        """Write a light-group layer of a mesh's lightmap as OpenEXR (R, G, B, error, hits), atomically."""
        _check(_C.plm_result_write_layer_exr(self._h, _uint(mesh_id, "mesh_id"), self._layer(layer),
                                             os.fsencode(os.fspath(path))))

    @property
    def directional(self):
        """True when the bake kept its light's directions (Scene.bake(directional=True))."""
        return bool(_C.plm_result_directional(self._h))

    def lightmap_sh(self, mesh_id):
        """A directional bake's SH L1 of a mesh's lightmap: a float32 array (4, h, w, 3) of the bands
        L0, L1_-1, L1_0, L1_1 in Godot 4's layout (photonlm.h, "Directional lightmaps"): a surface of
        unit world normal n receives 0.282095 L0 + 0.32573 (L1_-1 n.y + L1_0 n.z + L1_1 n.x)."""
        w, h = self.lightmap_size(mesh_id)
        out = np.empty((4, h, w, 3), np.float32)
        for band in range(4):
            _check(_C.plm_result_copy_lightmap_sh(self._h, mesh_id, band, _ptr(out[band], ctypes.c_float)))
        return out

    def write_sh_exr(self, mesh_id, band, path):
        """Write SH band `band` (0: L0 .. 3: L1_1) of a mesh's lightmap as OpenEXR (R, G, B, hits), atomically."""
        _check(_C.plm_result_write_sh_exr(self._h, _uint(mesh_id, "mesh_id"), _uint(band, "band"),
                                          os.fsencode(os.fspath(path))))

    def orientation_lightmap(self, group):
        """Copy an OL group's map into new numpy arrays (an OrientationLightmap)."""
        group = _uint(group, "group")
        rgb, err, area, hits = (_lib.FloatPtr() for _ in range(4))
        n = ctypes.c_uint32()
        _check(_C.plm_result_ol(self._h, group, ctypes.byref(rgb), ctypes.byref(err), ctypes.byref(n)))
        _check(_C.plm_result_ol_bins(self._h, group, ctypes.byref(area), ctypes.byref(hits)))
        n = n.value

        def copy(ptr, shape):
            return np.ctypeslib.as_array(ptr, shape=shape).copy()
        return OrientationLightmap(copy(rgb, (n, n, 3)), copy(err, (n, n)), n, copy(area, (n, n)),
                                   copy(hits, (n, n)))

    def ol_stats(self, group):
        """dict: resolution, mesh_count, hits, area (m^2), flux (W recorded), orphan_flux (W)."""
        s = _lib.plm_ol_stats()
        _check(_C.plm_result_ol_stats(self._h, _uint(group, "group"), ctypes.byref(s)))
        return {k: getattr(s, k) for k, _ in s._fields_ if k != "struct_size"}

    def write_ol_exr(self, group, path):
        """Write an OL group's map as OpenEXR (R, G, B, area, error, hits), atomically."""
        _check(_C.plm_result_write_ol_exr(self._h, _uint(group, "group"), os.fsencode(os.fspath(path))))

    def lsystem_lookup(self, lsystem, points, normals):
        """The light (irradiance / pi, RGB) at surface points of an L-system object.

        points, normals: (N, 3) world space. Each point uses the stub OL of the instance it lies on
        when that stub's bin holds enough hits, else the object's root OL. Returns (N, 3) float32."""
        p = np.ascontiguousarray(np.asarray(points, np.float32).reshape(-1, 3))
        n = np.ascontiguousarray(np.asarray(normals, np.float32).reshape(-1, 3))
        if p.shape != n.shape:
            raise ValueError("points and normals must have the same shape, got %s and %s" % (p.shape, n.shape))
        out = np.zeros(p.shape, np.float32)
        _check(_C.plm_result_lsystem_lookup(self._h, _uint(lsystem, "lsystem"), p.shape[0], _ptr(p, ctypes.c_float),
                                            _ptr(n, ctypes.c_float), _ptr(out, ctypes.c_float)))
        return out

    def lsystem_stats(self, lsystem):
        """dict: stubs (stub OLs with hits), stub_instances, hits, classes, primitives (flattened for
        the areas), truncated, resolution, cache_hits, cache_misses, cache_bytes, class_bytes,
        area (m^2), flux (W arriving on the object)."""
        s = _lib.plm_lsystem_stats()
        _check(_C.plm_result_lsystem_stats(self._h, _uint(lsystem, "lsystem"), ctypes.byref(s)))
        return {k: getattr(s, k) for k, _ in s._fields_ if k != "struct_size"}

    def write_exr(self, mesh_id, path):
        """Write a mesh's lightmap as OpenEXR (R, G, B, error, hits), atomically."""
        _check(_C.plm_result_write_exr(self._h, _uint(mesh_id, "mesh_id"), os.fsencode(os.fspath(path))))
