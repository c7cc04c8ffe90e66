"""Writes scenes as JSON scene files (docs/scene-file.md) for `photonlm bake SCENE -o DIR`.

SceneFileWriter has the scene-building methods of photonlm.Scene (add_material, add_mesh,
add_subdiv_mesh, add_light, set_world, set_world_map, set_world_map_file, add_csg, set_csg_carrier,
add_ol_group, set_ol_group_backup, set_mesh_ol_group, add_light_group, set_light_group,
add_material_lobe, set_material_texture, set_mesh_texture_uv, set_mesh_normals, set_mesh_smooth,
set_conventions) with the
same arguments and the
same returned ids, so code that builds a
photonlm.Scene can build a file instead:

    from photonlm.scene_file import SceneFileWriter
    w = SceneFileWriter()
    grey = w.add_material(0.6, name="grey")
    floor = w.add_mesh("floor", positions, triangles, lightmap_uv=uv, material_ids=mats, resolution=64)
    w.add_light("SUN", power=3.0, matrix=sun_matrix)
    w.set_settings(photons=2_000_000, target_error=0.02, seed=1)   # the arguments of Scene.bake
    w.write("scene.json")                                            # + scene_meshes/*.obj if large

Numbers are written so that the reader gets back the same float32 values the bridge would
pass to the engine: a file bake with the same settings and seed gives the same lightmaps.
Meshes are inline unless they have more than `obj_threshold` triangles; those go to OBJ files
beside the scene file (exact floats, one `vt` per triangle corner, `usemtl` per material run).
Meshes with texture UVs or normals stay inline (the reader takes texture_uv and normals for inline
meshes only).
Subdivision cages (add_subdiv_mesh) are always inline, as the cage with a "subdivision" object
(level, face sizes, creases): `photonlm bake` refines them as the bridge does; they take no
texture UVs (the reader refuses texture_uv on a cage).
Texture images are copied into <stem>_textures/ beside the scene file, and so is a world map file;
a world map given as pixels (set_world_map) is written there as a PFM (exact float32). Calls the file format
cannot hold (L-systems, texture UVs on a cage, and anything added to photonlm.Scene later) raise
SceneFileUnsupported naming the call.
"""
import json
import math
import os
import re
import shutil
import tempfile

import numpy as np

from . import _SETTING_FIELDS, _cage, _indices, _rgb, _uint
from . import _resolution as _bridge_resolution

__all__ = ["SceneFileWriter", "SceneFileUnsupported", "file_name"]

_LIGHT_TYPES = ("POINT", "SPOT", "SUN", "AREA_RECT", "AREA_DISK", "PORTAL")
_TEXTURE_SLOTS = ("albedo", "emission")
_LOBE_KINDS = ("glossy", "fresnel", "glass", "refraction", "transparent", "specular")
_CONVENTIONS = ("cycles-3.4", "cycles-4")
_COLORSPACES = ("auto", "linear", "srgb")
_CSG_SHAPES = ("SPHERE", "BOX", "CYLINDER", "CONE", "TORUS", "PARABOLOID", "HALF_SPACE")
_CSG_OPS = ("UNION", "INTERSECTION", "DIFFERENCE")
# Scene.bake argument -> scene file settings field (the C struct's field names).
_SETTINGS = _SETTING_FIELDS


class SceneFileUnsupported(NotImplementedError, AttributeError):
    """A photonlm.Scene call that the scene file format cannot hold (yet). Also an AttributeError,
    so that hasattr(writer, "method") is False for methods the writer lacks."""


def file_name(name, suffix, used):
    """The file `photonlm bake` writes for a mesh or OL group called name (bake_command.cpp):
    letters, digits, '.', '-', '_' kept, others '_'; duplicates (ignoring case) numbered.
    used: set of lower-case names already taken (updated)."""
    base = re.sub(r"[^A-Za-z0-9._-]", "_", name).lstrip(".")[:100] or "unnamed"
    n = 1
    while True:
        f = (base if n == 1 else "%s_%d" % (base, n)) + suffix
        if f.lower() != "report.json" and f.lower() not in used:
            used.add(f.lower())
            return f
        n += 1


def _floats(a, what):
    """float32 array -> list of Python floats (exact: each float32 is a double)."""
    a = np.ascontiguousarray(a, dtype=np.float32)
    if a.size and not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        raise ValueError("%s[%s] = %r is not finite (a scene file holds finite numbers only)"
                         % (what, ", ".join(map(str, bad)), float(a[tuple(bad)])))
    return a.ravel().tolist()


def _real(x):
    """A float as the engine's float32 sees it, exactly."""
    return float(np.float32(x))


def _resolution(resolution):
    w, h = _bridge_resolution(resolution)
    if (w == 0) != (h == 0):
        raise ValueError("resolution: width and height must both be 0 or both > 0, got %d x %d" % (w, h))
    return w, h


class SceneFileWriter:
    """Records photonlm.Scene calls and writes them as a scene file (see the module doc)."""

    def __init__(self, obj_threshold=200_000):
        self.obj_threshold = int(obj_threshold)
        self.materials = []      # dicts
        self.meshes = []         # dicts; big arrays kept as numpy until write()
        self.lights = []
        self.ol_groups = []
        self.csg = []
        self.world = None
        self.world_pixels = None  # set_world_map's (H, W, 3) float32 pixels, written on write()
        self.light_groups = []   # names; ids are 1, 2, ... (0: the default group)
        self.world_group = 0     # the world's light group id
        self.settings = {}
        self.metadata = None
        self.conventions = "cycles-3.4"

    def set_conventions(self, conventions):
        if conventions not in _CONVENTIONS:
            raise ValueError("conventions must be one of %s, got %r" % (list(_CONVENTIONS), conventions))
        self.conventions = conventions

    # -- photonlm.Scene's methods ---------------------------------------------------------------
    def add_material(self, albedo, emission=(0.0, 0.0, 0.0), name=None):
        albedo, emission = _rgb(albedo, "albedo"), _rgb(emission, "emission")
        label = "material %d%s" % (len(self.materials), "" if name is None else " '%s'" % name)
        m = {"albedo": _floats(albedo, label + " albedo"), "emission": _floats(emission, label + " emission")}
        if not all(0.0 <= c <= 1.0 for c in m["albedo"]):
            raise ValueError("%s: albedo %s is not in [0, 1]" % (label, m["albedo"]))
        if min(m["emission"]) < 0.0:
            raise ValueError("%s: emission %s is negative" % (label, m["emission"]))
        if name is not None:
            m["name"] = str(name)
        self.materials.append(m)
        return len(self.materials) - 1

    def add_mesh(self, name, positions, triangles, lightmap_uv=None, material_ids=None, resolution=0):
        pos = np.ascontiguousarray(positions, dtype=np.float32)
        if pos.ndim != 2 or pos.shape[1] != 3:
            raise ValueError("positions of mesh %r must have shape (V, 3), got %s" % (name, pos.shape))
        tri = _indices(triangles, "triangles")
        if tri.ndim != 2 or tri.shape[1] != 3 or tri.shape[0] == 0:
            raise ValueError("triangles of mesh %r must have shape (T, 3) with T > 0, got %s" % (name, tri.shape))
        t = tri.shape[0]
        if tri.max() >= pos.shape[0]:
            bad = np.argwhere(tri >= pos.shape[0])[0]
            raise ValueError("mesh %r: triangles[%d, %d] = %d is out of range (%d vertices)"
                             % (name, bad[0], bad[1], tri[tuple(bad)], pos.shape[0]))
        _floats(pos, "mesh %r positions" % name)
        width, height = _resolution(resolution)
        uv = None
        if width:
            if lightmap_uv is None:
                raise ValueError("mesh %r has a lightmap (resolution %d x %d) but no lightmap_uv" % (name, width, height))
            uv = np.ascontiguousarray(lightmap_uv, dtype=np.float32)
            if uv.shape not in ((t, 3, 2), (3 * t, 2)):
                raise ValueError("lightmap_uv of mesh %r must have shape (T, 3, 2) or (3T, 2) with "
                                 "T = %d triangles, got %s" % (name, t, uv.shape))
            _floats(uv, "mesh %r lightmap_uv" % name)
            uv = uv.reshape(t * 3, 2)
        mats = None
        if material_ids is not None:
            mats = _indices(material_ids, "material_ids")
            if mats.shape != (t,):
                raise ValueError("material_ids of mesh %r must have shape (T,) with T = %d triangles, "
                                 "got %s" % (name, t, mats.shape))
            if mats.max() >= max(len(self.materials), 1):
                raise ValueError("mesh %r: material id %d is out of range (%d materials)"
                                 % (name, int(mats.max()), len(self.materials)))
        self.meshes.append({"name": str(name), "positions": pos, "triangles": tri, "uv": uv, "materials": mats,
                            "resolution": (width, height), "ol_group": None, "texture_uv": None,
                            "normals": None, "smooth": False})
        return len(self.meshes) - 1

    def add_subdiv_mesh(self, name, positions, face_sizes, face_indices, level, lightmap_uv=None,
                        material_ids=None, crease_edges=None, crease_weights=None, resolution=0):
        """photonlm.Scene.add_subdiv_mesh: a Catmull-Clark cage, written inline as a mesh with a
        "subdivision" object (the engine refines it when it bakes the file, never this writer).
        The checks of the bridge (its _cage) plus those the file reader and the engine would make
        later, so a bad cage fails here naming the mesh and the index."""
        pos, sizes, fidx, uv, edges, weights, _ = _cage(name, positions, face_sizes, face_indices,
                                                        lightmap_uv, crease_edges, crease_weights)
        level = _uint(level, "level")
        if not 1 <= level <= 10:
            raise ValueError("mesh %r: subdivision level %d is not in [1, 10]" % (name, level))
        if sizes.shape[0] == 0:
            raise ValueError("mesh %r: a subdivision cage needs at least one face" % (name,))
        if sizes.min() < 3 or sizes.max() > 65536:
            f = int(np.argmax((sizes < 3) | (sizes > 65536)))
            raise ValueError("mesh %r: cage face %d has %d corners (3 to 65536 allowed)" % (name, f, sizes[f]))
        corners = fidx.shape[0]
        triangles = 2 * corners * 4 ** (level - 1)
        if triangles > 1 << 25:
            raise ValueError("mesh %r: level %d makes %d triangles from %d face corners, more than 2^25"
                             % (name, level, triangles, corners))
        nv = pos.shape[0]
        if fidx.max() >= nv:
            k = int(np.argmax(fidx >= nv))
            f = int(np.searchsorted(np.cumsum(sizes, dtype=np.int64), k, side="right"))
            raise ValueError("mesh %r: cage face %d (face_indices[%d]) uses vertex %d, out of range (%d vertices)"
                             % (name, f, k, fidx[k], nv))
        _floats(pos, "mesh %r positions" % name)
        if edges is not None and edges.shape[0]:
            if edges.max() >= nv:
                bad = np.argwhere(edges >= nv)[0]
                raise ValueError("mesh %r: crease_edges[%d, %d] = %d is out of range (%d vertices)"
                                 % (name, bad[0], bad[1], edges[tuple(bad)], nv))
            _floats(weights, "mesh %r crease_weights" % name)
            if weights.min() < 0.0 or weights.max() > 1.0:
                c = int(np.argmax((weights < 0.0) | (weights > 1.0)))
                raise ValueError("mesh %r: crease_weights[%d] = %r is not in [0, 1]" % (name, c, float(weights[c])))
            # Each crease must be an edge of the cage (the engine's check, made here to fail early).
            nxt = np.arange(corners, dtype=np.int64) + 1
            last = np.cumsum(sizes, dtype=np.int64) - 1
            nxt[last] = last - sizes + 1
            a, b = fidx.astype(np.int64), fidx[nxt].astype(np.int64)
            cage_edges = np.unique(np.minimum(a, b) * nv + np.maximum(a, b))
            e = edges.astype(np.int64)
            keys = np.minimum(e[:, 0], e[:, 1]) * nv + np.maximum(e[:, 0], e[:, 1])
            missing = ~np.isin(keys, cage_edges)
            if missing.any():
                c = int(np.argmax(missing))
                raise ValueError("mesh %r: crease %d names the edge %d-%d, which no cage face has"
                                 % (name, c, e[c, 0], e[c, 1]))
        width, height = _resolution(resolution)
        if width:
            if uv is None:
                raise ValueError("mesh %r has a lightmap (resolution %d x %d) but no lightmap_uv" % (name, width, height))
            _floats(uv, "mesh %r lightmap_uv" % name)
        else:
            uv = None  # the engine ignores the UVs of a mesh without a lightmap; the reader refuses them
        mats = None
        if material_ids is not None:
            mats = _indices(material_ids, "material_ids")
            if mats.shape != sizes.shape:
                raise ValueError("material_ids of mesh %r must have shape (F,) = %s, got %s"
                                 % (name, sizes.shape, mats.shape))
            if mats.max() >= max(len(self.materials), 1):
                f = int(np.argmax(mats >= max(len(self.materials), 1)))
                raise ValueError("mesh %r: cage face %d uses material %d, out of range (%d materials)"
                                 % (name, f, int(mats[f]), len(self.materials)))
        self.meshes.append({"name": str(name), "positions": pos, "triangles": None, "uv": uv, "materials": mats,
                            "resolution": (width, height), "ol_group": None, "texture_uv": None,
                            "normals": None, "smooth": False,
                            "subdivision": {"level": level, "face_sizes": sizes, "face_indices": fidx,
                                            "crease_edges": edges, "crease_weights": weights}})
        return len(self.meshes) - 1

    def add_light(self, type, *, name=None, color=None, power=None, matrix=None, radius=None,
                  angle=None, size=None, size_y=None, spot_size=None, spot_blend=None):
        kind = str(type).upper()
        if kind not in _LIGHT_TYPES:
            raise ValueError("light type must be one of %s, got %r" % (", ".join(_LIGHT_TYPES), type))
        label = "light %d%s" % (len(self.lights), "" if name is None else " '%s'" % name)
        light = {"type": kind}
        if name is not None:
            light["name"] = str(name)
        if color is not None:
            light["color"] = _floats(_rgb(color, "color"), label + " color")
        if matrix is not None:
            m = np.array(matrix, dtype=np.float32)
            if m.shape != (4, 4):
                raise ValueError("%s: matrix must be 4x4, got shape %s" % (label, m.shape))
            light["matrix"] = _floats(m, label + " matrix")
        if size is not None and size_y is None:
            size_y = size
        for field, value in (("power", power), ("radius", radius), ("angle", angle), ("size_x", size),
                             ("size_y", size_y), ("spot_size", spot_size), ("spot_blend", spot_blend)):
            if value is not None:
                v = _real(value)
                if not math.isfinite(v):
                    raise ValueError("%s: %s = %r is not finite" % (label, field, value))
                light[field] = v
        self.lights.append(light)
        return len(self.lights) - 1

    def add_csg(self, name, primitives, tree):
        prims = []
        for i, p in enumerate(primitives):
            shape = p.get("shape")
            if shape not in _CSG_SHAPES:
                raise ValueError("CSG %r primitive %d shape must be one of %s, got %r"
                                 % (name, i, ", ".join(_CSG_SHAPES), shape))
            m = np.asarray(p.get("matrix", np.eye(4)), np.float64)
            if m.shape not in ((3, 4), (4, 4)):
                raise ValueError("CSG %r primitive %d: matrix must be 3x4 or 4x4, got %s" % (name, i, m.shape))
            if not np.all(np.isfinite(m[:3])):
                raise ValueError("CSG %r primitive %d: matrix is not finite" % (name, i))
            material = _uint(p.get("material", 0), "primitive %d material" % i)
            prims.append({"shape": shape, "material": material, "matrix": m[:3].ravel().tolist(),
                          "major_radius": float(p.get("major_radius", 1.0)),
                          "minor_radius": float(p.get("minor_radius", 0.25))})
        nodes, children = [], []

        def add(node):  # the same node order as photonlm.Scene.add_csg
            if isinstance(node, (tuple, list)):
                if node[0] not in _CSG_OPS:
                    raise ValueError("CSG %r: tree operator must be one of %s, got %r"
                                     % (name, ", ".join(_CSG_OPS), node[0]))
                index = len(nodes)
                nodes.append({"op": node[0], "first": 0, "count": len(node) - 1})
                kids = [add(child) for child in node[1:]]
                nodes[index]["first"] = len(children)
                children.extend(kids)
                return index
            leaf = _uint(node, "tree leaf")
            if leaf >= len(prims):
                raise ValueError("CSG %r: tree leaf %d is out of range (%d primitives)" % (name, leaf, len(prims)))
            nodes.append({"op": "LEAF", "first": leaf})
            return len(nodes) - 1
        root = add(tree)
        self.csg.append({"name": str(name), "primitives": prims, "nodes": nodes, "children": children,
                         "root": root})
        return len(self.csg) - 1

    def set_csg_carrier(self, csg, mesh):
        csg, mesh = self._index(csg, self.csg, "csg"), self._index(mesh, self.meshes, "mesh")
        if self.meshes[mesh]["resolution"][0] == 0:
            raise ValueError("mesh %r has no lightmap: it cannot carry CSG %r"
                             % (self.meshes[mesh]["name"], self.csg[csg]["name"]))
        self.csg[csg]["carrier"] = mesh

    def add_ol_group(self, name=None, resolution=0):
        resolution = _uint(resolution, "resolution")
        if resolution > 1024:
            raise ValueError("OL group resolution must be at most 1024, got %d" % resolution)
        g = {"resolution": resolution}
        if name is not None:
            g["name"] = str(name)
        self.ol_groups.append(g)
        return len(self.ol_groups) - 1

    def set_ol_group_backup(self, group, backup=True):
        self.ol_groups[self._index(group, self.ol_groups, "group")]["backup"] = bool(backup)

    def set_ol_group_limit_area(self, group, limit_area=True):
        self.ol_groups[self._index(group, self.ol_groups, "group")]["limit_area"] = bool(limit_area)

    def set_mesh_ol_group(self, mesh, group):
        mesh = self._index(mesh, self.meshes, "mesh")
        self.meshes[mesh]["ol_group"] = self._index(group, self.ol_groups, "group")

    def add_light_group(self, name):
        name = str(name)
        label = "light group '%s'" % name
        if not re.fullmatch(r"[A-Za-z0-9_-]{1,64}", name):
            raise ValueError("%s: the name must be 1 to 64 letters, digits, '_' and '-'" % label)
        if name == "default" or name in self.light_groups:
            raise ValueError("%s: %s" % (label, "'default' is the default group's name" if name == "default"
                                         else "a light group of that name exists"))
        self.light_groups.append(name)
        return len(self.light_groups)

    def set_light_group(self, group, *, light=None, mesh=None, world=False):
        if (light is not None) + (mesh is not None) + bool(world) != 1:
            raise ValueError("set_light_group: give exactly one of light=, mesh= and world=True")
        group = _uint(group, "group")
        if group > len(self.light_groups):
            raise ValueError("light group %d does not exist (%d declared; 0 is the default group)"
                             % (group, len(self.light_groups)))
        if world:
            self.world_group = group
            return
        items, what = (self.lights, "light") if light is not None else (self.meshes, "mesh")
        item = items[self._index(light if light is not None else mesh, items, what)]
        item.pop("group", None)
        if group:
            item["group"] = self.light_groups[group - 1]

    def add_material_lobe(self, material, kind, color, roughness=0.0, ior=None, abbe=0.0, weight=1.0):
        material = self._index(material, self.materials, "material")
        if kind not in _LOBE_KINDS:
            raise ValueError("lobe kind must be one of %s, got %r" % (list(_LOBE_KINDS), kind))
        m = self.materials[material]
        lobes = m.setdefault("lobes", [])
        label = "material %d lobe %d (%s)" % (material, len(lobes), kind)
        if len(lobes) >= 8:
            raise ValueError("material %d: has 8 lobes already, the most a material may have" % material)
        lobe = {"type": kind, "color": _floats(_rgb(color, label + " color"), label + " color"),
                "weight": _real(weight), "roughness": _real(roughness), "abbe": _real(abbe)}
        for key in ("weight", "roughness"):
            if not 0.0 <= lobe[key] <= 1.0:
                raise ValueError("%s: %s %r is not in [0, 1]" % (label, key, lobe[key]))
        if not all(0.0 <= c <= 1.0 for c in lobe["color"]):
            raise ValueError("%s: color %s is not in [0, 1]" % (label, lobe["color"]))
        if ior is not None:
            lobe["ior"] = _real(ior)
            if not 0.0 < lobe["ior"] < 1e6:
                raise ValueError("%s: ior %r must be > 0 and finite" % (label, lobe["ior"]))
        if not 0.0 <= lobe["abbe"] < 1e6:
            raise ValueError("%s: abbe %r must be >= 0 and finite" % (label, lobe["abbe"]))
        lobes.append(lobe)

    def set_material_diffuse(self, material, model, roughness=0.0):
        material = self._index(material, self.materials, "material")
        if model not in ("lambert", "burley"):
            raise ValueError("diffuse model must be one of ['burley', 'lambert'], got %r" % (model,))
        m = self.materials[material]
        m.pop("burley_roughness", None)
        if model == "burley":
            r = _real(roughness)
            if not 0.0 <= r <= 1.0:
                raise ValueError("material %d: diffuse roughness %r is not in [0, 1]" % (material, r))
            m["burley_roughness"] = r

    def set_material_texture(self, material, slot, path, colorspace="auto"):
        material = self._index(material, self.materials, "material")
        if slot not in _TEXTURE_SLOTS:
            raise ValueError("texture slot must be one of %s, got %r" % (list(_TEXTURE_SLOTS), slot))
        if colorspace not in _COLORSPACES:
            raise ValueError("colorspace must be one of %s, got %r" % (list(_COLORSPACES), colorspace))
        key = slot + "_texture"
        if not path:
            self.materials[material].pop(key, None)
            return
        path = os.path.abspath(os.fspath(path))
        if not os.path.isfile(path):
            raise ValueError("material %d %s texture: no such file %s" % (material, slot, path))
        self.materials[material][key] = {"path": path, "colorspace": colorspace}

    def set_mesh_texture_uv(self, mesh, uv):
        mesh = self._index(mesh, self.meshes, "mesh")
        m = self.meshes[mesh]
        if uv is None:
            m["texture_uv"] = None
            return
        if "subdivision" in m:
            raise SceneFileUnsupported("mesh %r is a subdivision cage: the scene file format takes no texture_uv "
                                       "for subdivision meshes (export the refined mesh instead)" % m["name"])
        t = len(m["triangles"])
        arr = np.ascontiguousarray(uv, dtype=np.float32)
        if arr.shape not in ((t, 3, 2), (3 * t, 2)):
            raise ValueError("texture uv of mesh %r must have shape (T, 3, 2) or (3T, 2) with T = %d, got %s"
                             % (m["name"], t, arr.shape))
        _floats(arr, "mesh %r texture uv" % m["name"])
        m["texture_uv"] = arr.reshape(3 * t, 2)

    def set_mesh_normals(self, mesh, normals):
        mesh = self._index(mesh, self.meshes, "mesh")
        m = self.meshes[mesh]
        if normals is None:
            m["normals"] = None
            return
        if "subdivision" in m:
            raise SceneFileUnsupported("mesh %r is a subdivision cage: the scene file format takes no normals for "
                                       "subdivision meshes (set_mesh_smooth, or export the refined mesh)" % m["name"])
        t = len(m["triangles"])
        arr = np.ascontiguousarray(normals, dtype=np.float32)
        if arr.shape not in ((t, 3, 3), (3 * t, 3)):
            raise ValueError("normals of mesh %r must have shape (T, 3, 3) or (3T, 3) with T = %d, got %s"
                             % (m["name"], t, arr.shape))
        _floats(arr, "mesh %r normals" % m["name"])
        m["normals"], m["smooth"] = arr.reshape(3 * t, 3), False

    def set_mesh_smooth(self, mesh, smooth=True):
        m = self.meshes[self._index(mesh, self.meshes, "mesh")]
        m["smooth"], m["normals"] = bool(smooth), None

    def refine_subdiv_meshes(self, threads=0):
        """photonlm.Scene.refine_subdiv_meshes: nothing to write (the engine refines the cages when
        it bakes the file)."""

    def set_world(self, radiance):
        self.world = {"radiance": _floats(_rgb(radiance, "radiance"), "world radiance")}
        self.world_pixels = None

    def set_world_map(self, rgb, rotation=None, strength=1.0):
        a = np.ascontiguousarray(rgb, dtype=np.float32)
        if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] == 0 or a.shape[1] == 0:
            raise ValueError("world map rgb must have shape (H, W, 3), got %s" % (a.shape,))
        bad = np.argwhere(~(np.isfinite(a) & (a >= 0)))
        if len(bad):
            r, c, k = bad[0]
            raise ValueError("world map: pixel at row %d, column %d (row 0 = top) has %s = %r; radiance must be "
                             "finite and >= 0" % (r, c, "RGB"[k], float(a[r, c, k])))
        self.world = self._world_map_fields(None, rotation, strength)
        self.world_pixels = a.copy()  # written as a PFM beside the scene file (exact float32)

    def set_world_map_file(self, path, rotation=None, strength=1.0):
        path = os.path.abspath(os.fspath(path))
        if not os.path.isfile(path):
            raise ValueError("world map: no such file %s" % path)
        self.world = self._world_map_fields(path, rotation, strength)
        self.world_pixels = None

    @staticmethod
    def _world_map_fields(path, rotation, strength):
        w = {"map": path}
        if rotation is not None:
            r = np.asarray(rotation, dtype=np.float32).reshape(-1)
            if r.shape != (9,):
                raise ValueError("rotation must be a 3x3 matrix (9 floats), got %d values" % r.size)
            w["rotation"] = _floats(r, "world map rotation")
        strength = _real(strength)
        if not (math.isfinite(strength) and strength >= 0.0):
            raise ValueError("world map strength must be a finite number >= 0, got %r" % strength)
        w["strength"] = strength
        return w

    def add_lsystem(self, name, *args, **kwargs):
        raise SceneFileUnsupported("L-system %r: the scene file format has no L-systems yet "
                                   "(bake it in Blender or through photonlm.Scene)" % name)

    def __getattr__(self, attr):
        # Called only for attributes that do not exist: a photonlm.Scene call this writer lacks.
        if attr.startswith("__"):
            raise AttributeError(attr)
        raise SceneFileUnsupported("the scene file writer cannot record photonlm.Scene.%s: the scene file "
                                   "format (docs/scene-file.md) has no such field yet" % attr)

    def close(self):
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    # -- settings and writing -------------------------------------------------------------------
    def set_settings(self, **bake_arguments):
        """Bake settings by the names of photonlm.Scene.bake (photons, seed, target_error...)."""
        for key, value in bake_arguments.items():
            if key not in _SETTINGS:
                raise ValueError("unknown bake setting %r (known: %s)" % (key, ", ".join(_SETTINGS)))
            if key in ("texel_value", "sampler"):
                value = str(value)
            elif key == "directional":
                if value not in (True, False):
                    raise ValueError("directional must be True or False, got %r" % (value,))
                value = bool(value)
            elif key in ("target_error", "time_budget"):
                value = float(value)
                if not value >= 0.0 or not math.isfinite(value):
                    raise ValueError("%s must be a finite number >= 0, got %r" % (key, value))
            else:
                value = _uint(value, key, 40 if key == "photons" else 32)
            self.settings[_SETTINGS[key]] = value

    def output_files(self):
        """{mesh name: EXR file name} that `photonlm bake` writes for the meshes with a lightmap,
        and {OL group name: EXR file name}: in the order the CLI names them."""
        used = set()
        meshes = {}
        for i, m in enumerate(self.meshes):
            if m["resolution"][0]:
                meshes[m["name"]] = file_name(m["name"], "_lightmap.exr", used)
        groups = {}
        for i, g in enumerate(self.ol_groups):
            n = g.get("name", "ol%d" % i)
            groups[n] = file_name(n, "_ol.exr", used)
        return meshes, groups

    def to_json(self, mesh_dir=None, mesh_dir_rel=None, texture_dir=None, texture_dir_rel=None):
        """The scene as a JSON-ready dict; meshes above obj_threshold triangles are written as OBJ
        files into mesh_dir (named in the file as mesh_dir_rel/...), or kept inline if mesh_dir is None.
        Texture images are copied into texture_dir (named texture_dir_rel/...), or named by their
        absolute paths if texture_dir is None."""
        materials = [dict(m) for m in self.materials]
        copied = {}  # source path -> name in the file
        used = set()
        for m in materials:
            for key in ("albedo_texture", "emission_texture"):
                if key not in m:
                    continue
                src = m[key]["path"]
                if src not in copied:
                    if texture_dir is None:
                        copied[src] = src
                    else:
                        os.makedirs(texture_dir, exist_ok=True)
                        stem, ext = os.path.splitext(os.path.basename(src))
                        fname = file_name(stem, ext, used)
                        shutil.copyfile(src, os.path.join(texture_dir, fname))
                        copied[src] = (texture_dir_rel + "/" if texture_dir_rel else "") + fname
                m[key] = {"path": copied[src], "colorspace": m[key]["colorspace"]}
        texture_names = used
        big = [i for i, m in enumerate(self.meshes) if mesh_dir is not None and "subdivision" not in m
               and m["texture_uv"] is None and m["normals"] is None and len(m["triangles"]) > self.obj_threshold]
        if big:  # usemtl takes one whitespace-free token: give every material a unique one
            used = set()
            for i, m in enumerate(materials):
                base = re.sub(r"\s+", "_", m.get("name") or "material%d" % i)
                n, k = base, 1
                while n in used:
                    k += 1
                    n = "%s.%d" % (base, k)
                used.add(n)
                m["name"] = n
        meshes = []
        obj_names = set()
        for i, m in enumerate(self.meshes):
            e = {"name": m["name"]}
            w, h = m["resolution"]
            mats = m["materials"]
            one = mats is not None and len(mats) and np.all(mats == mats[0])
            if i in big:
                os.makedirs(mesh_dir, exist_ok=True)
                fname = file_name(m["name"], ".obj", obj_names)
                self._write_obj(os.path.join(mesh_dir, fname), m, materials)
                e["obj"] = (mesh_dir_rel + "/" if mesh_dir_rel else "") + fname
                if mats is not None and one:
                    e["material"] = int(mats[0])
            else:
                e["positions"] = _floats(m["positions"], "positions")
                sd = m.get("subdivision")
                if sd is None:
                    e["indices"] = m["triangles"].ravel().tolist()
                else:  # a cage, always inline: indices, lightmap_uv and materials are per face (corner)
                    e["indices"] = sd["face_indices"].tolist()
                    e["subdivision"] = {"level": sd["level"], "face_sizes": sd["face_sizes"].tolist()}
                    if sd["crease_edges"] is not None and len(sd["crease_edges"]):
                        e["subdivision"]["creases"] = [
                            [int(v0), int(v1), c] for (v0, v1), c in
                            zip(sd["crease_edges"].tolist(), _floats(sd["crease_weights"], "crease_weights"))]
                if w:
                    e["lightmap_uv"] = _floats(m["uv"], "lightmap_uv")
                if mats is not None:
                    if one:
                        e["material"] = int(mats[0])
                    else:
                        e["materials"] = mats.tolist()
            if w:
                e["lightmap_resolution"] = [w, h] if w != h else w
            if m["texture_uv"] is not None:
                e["texture_uv"] = _floats(m["texture_uv"], "texture_uv")
            if m["normals"] is not None:
                e["normals"] = _floats(m["normals"], "normals")
            if m["smooth"]:
                e["smooth"] = True
            if m["ol_group"] is not None:
                e["ol_group"] = m["ol_group"]
            if "group" in m:
                e["group"] = m["group"]
            meshes.append(e)
        scene = {"version": 1}
        if self.conventions != "cycles-3.4":
            scene["conventions"] = self.conventions
        if self.metadata is not None:
            scene["metadata"] = self.metadata
        for key, value in (("light_groups", self.light_groups), ("materials", materials),
                           ("ol_groups", self.ol_groups), ("meshes", meshes),
                           ("lights", self.lights), ("csg", self.csg)):
            if value:
                scene[key] = value
        if self.world is not None:
            scene["world"] = dict(self.world)
            if self.world_group:
                scene["world"]["group"] = self.light_groups[self.world_group - 1]
            if "map" in self.world:
                scene["world"]["map"] = self._world_map_file(texture_dir, texture_dir_rel, copied, texture_names)
        if self.settings:
            scene["settings"] = dict(self.settings)
        return scene

    def write(self, path):
        """Write the scene file at path (atomically); big meshes go to <stem>_meshes/ beside it."""
        path = os.path.abspath(path)
        folder = os.path.dirname(path)
        stem = os.path.splitext(os.path.basename(path))[0]
        os.makedirs(folder, exist_ok=True)
        scene = self.to_json(os.path.join(folder, stem + "_meshes"), stem + "_meshes",
                             os.path.join(folder, stem + "_textures"), stem + "_textures")
        text = json.dumps(scene, separators=(",", ":"), allow_nan=False)
        _write_atomic(path, text + "\n")
        return path

    # -- helpers --------------------------------------------------------------------------------
    def _world_map_file(self, texture_dir, texture_dir_rel, copied, used):
        """The world map's name in the file: set_world_map's pixels written as a PFM (exact
        float32, rows bottom first as the format stores them), a file copied as the textures are."""
        src = self.world["map"]
        if self.world_pixels is None and (texture_dir is None or src in copied):
            return src if texture_dir is None else copied[src]
        if texture_dir is None:
            raise ValueError("a world map given as pixels needs a folder to be written to: use write()")
        os.makedirs(texture_dir, exist_ok=True)
        if self.world_pixels is None:
            stem, ext = os.path.splitext(os.path.basename(src))
            fname = file_name(stem, ext, used)
            shutil.copyfile(src, os.path.join(texture_dir, fname))
        else:
            fname = file_name("world_map", ".pfm", used)
            h, w, _ = self.world_pixels.shape
            data = b"PF\n%d %d\n-1.0\n" % (w, h) + np.ascontiguousarray(self.world_pixels[::-1]).astype("<f4").tobytes()
            with open(os.path.join(texture_dir, fname), "wb") as f:
                f.write(data)
        return (texture_dir_rel + "/" if texture_dir_rel else "") + fname

    @staticmethod
    def _index(i, items, what):
        i = _uint(i, what)
        if i >= len(items):
            raise ValueError("%s id %d is out of range (%d so far)" % (what, i, len(items)))
        return i

    @staticmethod
    def _write_obj(path, m, materials):
        pos, tri, uv, mats = m["positions"], m["triangles"], m["uv"], m["materials"]
        out = ["# photonlm scene file mesh '%s': one vt per triangle corner\n" % m["name"]]
        out.extend("v %r %r %r\n" % tuple(p) for p in pos.astype(np.float64).tolist())
        if uv is not None:
            out.extend("vt %r %r\n" % tuple(t) for t in uv.astype(np.float64).tolist())
        current = None
        for k, (a, b, c) in enumerate((tri + 1).tolist()):
            if mats is not None and mats[k] != current:
                current = int(mats[k])
                out.append("usemtl %s\n" % materials[current]["name"])
            if uv is not None:
                out.append("f %d/%d %d/%d %d/%d\n" % (a, 3 * k + 1, b, 3 * k + 2, c, 3 * k + 3))
            else:
                out.append("f %d %d %d\n" % (a, b, c))
        _write_atomic(path, "".join(out))


def _write_atomic(path, text):
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", dir=os.path.dirname(path))
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
