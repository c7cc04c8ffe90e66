"""The world as the engine takes it (docs/design/lights.md, "Skies and other worlds from Blender").

- No nodes, or a Background whose Color and Strength are not linked: a uniform radiance.
- A Background fed by an Environment Texture (equirectangular, optionally through a Mapping node
  fed by the Texture Coordinate's Generated or Object output): the image goes to the engine
  directly, as its file (float files in a linear colour space, 8-bit sRGB files) or as its pixels,
  with the Mapping node's rotation and the Background's strength.
- Anything else (Sky Texture, gradients, mixes, Light Path tricks): Blender renders the world
  itself into an equirectangular map with Cycles, in a separate Blender process
  (world_render_child.py: a scene holding only the world and a panoramic camera at the origin,
  RENDER_SIZE pixels, a box pixel filter so each pixel is the mean radiance over its solid angle
  and a small sun keeps its energy; Light Path nodes answer as for a diffuse ray). The world goes
  there as a library file in a temporary folder, removed afterwards; the user's session gains
  nothing (no scene, camera or image; its Render Result keeps the last render).
"""
import math
import os
import shutil
import subprocess
import tempfile
import time

import bpy
import numpy as np
from mathutils import Euler

from .. import compat

RENDER_SIZE = (1024, 512)  # pixels of a rendered world: 0.35 degrees each
# Box-filtered samples per pixel: 16 to 1024, adaptive (noise threshold 0.01), so the smooth sky
# stops at 16 and the pixels a sun disc crosses go on until its share of each is found.
RENDER_SAMPLES = 1024
# Cycles draws a physical Sky Texture's sun disc limb-darkened, radiance ~ 0.4 + 0.6 sqrt(1 - (r/R)^2)
# (svm_sky.h), whose mean squared radius is 0.45 R^2; a uniform disc of the same mean squared radius
# (0.5 r^2 = 0.45 R^2) has sqrt(0.9) of its angle and casts the closest penumbra a sun lamp can (a
# sun shadow edge in test_sky_sun_disc: largest column difference from Cycles 1.2 % of the lit
# level, 2.5 % with the disc's own angle).
LIMB_DARKENED_SUN_ANGLE = math.sqrt(0.9)


def _source(socket):
    """(node, output socket) feeding an input socket, skipping reroutes; (None, None) if unlinked."""
    for _ in range(64):
        if socket is None or not socket.is_linked:
            return None, None
        link = socket.links[0]
        if link.is_muted or not link.is_valid:
            return None, None
        if link.from_node.bl_idname != 'NodeReroute':
            return link.from_node, link.from_socket
        socket = link.from_node.inputs[0]
    return None, None


class WorldSource:
    """What the world is for the engine: kind 'NONE', 'UNIFORM' (radiance), 'IMAGE' (image,
    rotation: 3x3 map -> world, strength) or 'RENDER' (why; sun_disc: see _sun_disc), with notes for
    the user."""

    def __init__(self, kind, **fields):
        self.kind = kind
        self.radiance = (0.0, 0.0, 0.0)
        self.image = None
        self.rotation = None
        self.strength = 1.0
        self.why = ""
        self.sun_disc = None
        self.notes = []
        self.__dict__.update(fields)


def _lookup_matrix(env):
    """The 3x3 matrix taking a world direction to the direction the Environment Texture looks up,
    or (None, why) when its Vector input is not a rotation of the world direction."""
    node, sock = _source(env.inputs['Vector'])
    if node is None:
        return np.eye(3), ""
    if node.bl_idname == 'ShaderNodeTexCoord':
        return (np.eye(3), "") if sock.name in ("Generated", "Object") else \
            (None, "the Environment Texture reads the Texture Coordinate's %s output" % sock.name)
    if node.bl_idname != 'ShaderNodeMapping':
        return None, "the Environment Texture's Vector comes from '%s'" % node.bl_label
    src, src_sock = _source(node.inputs['Vector'])
    if src is None or src.bl_idname != 'ShaderNodeTexCoord' or src_sock.name not in ("Generated", "Object"):
        return None, "the Mapping node does not read the Texture Coordinate's Generated output"
    for name in ("Location", "Rotation", "Scale"):
        if name in node.inputs and node.inputs[name].is_linked:
            return None, "the Mapping node's %s is linked" % name
    kind = node.vector_type
    loc = np.array(node.inputs['Location'].default_value) if 'Location' in node.inputs else np.zeros(3)
    scale = np.array(node.inputs['Scale'].default_value) if 'Scale' in node.inputs else np.ones(3)
    if kind in ('POINT', 'TEXTURE') and np.any(loc != 0.0):
        return None, "the Mapping node moves the coordinates (Location)"
    mag = np.abs(scale)
    if mag.min() <= 0.0 or mag.max() - mag.min() > 1e-6 * mag.max():
        return None, "the Mapping node scales unevenly"
    sign = np.diag(np.sign(scale))
    m = np.array(Euler(node.inputs['Rotation'].default_value, 'XYZ').to_matrix())
    # Blender's Mapping (measured against Cycles renders): Point / Vector look up M S d, Normal
    # M S^-1 d, Texture S^-1 M^T d; a uniform |S| drops out when the direction is normalised.
    return (sign @ m.T if kind == 'TEXTURE' else m @ sign), ""


def _texture_mapping_is_identity(env):
    tm = getattr(env, "texture_mapping", None)
    if tm is None:
        return True
    return (tuple(tm.translation) == (0, 0, 0) and tuple(tm.rotation) == (0, 0, 0) and tuple(tm.scale) == (1, 1, 1)
            and tm.mapping_x == 'X' and tm.mapping_y == 'Y' and tm.mapping_z == 'Z'
            and not tm.use_min and not tm.use_max)


def describe(world):
    """The WorldSource of a Blender world (reads the node tree only; renders nothing)."""
    if world is None:
        return WorldSource('NONE')
    if not compat.uses_nodes(world):
        return WorldSource('UNIFORM', radiance=tuple(max(float(c), 0.0) for c in world.color))
    out = world.node_tree.get_output_node('CYCLES')
    node, _ = _source(out.inputs['Surface']) if out is not None else (None, None)
    if node is None:
        return WorldSource('NONE')
    if node.bl_idname != 'ShaderNodeBackground':
        return WorldSource('RENDER', why="its surface is '%s', not a Background" % node.bl_label)
    col, strength = node.inputs['Color'], node.inputs['Strength']
    if strength.is_linked:
        return WorldSource('RENDER', why="the Background's Strength is linked")
    s = max(float(strength.default_value), 0.0)
    if not col.is_linked:
        return WorldSource('UNIFORM', radiance=tuple(max(float(c), 0.0) * s for c in col.default_value[:3]))
    src, sock = _source(col)
    if src is None:
        return WorldSource('UNIFORM', radiance=tuple(max(float(c), 0.0) * s for c in col.default_value[:3]))
    if src.bl_idname != 'ShaderNodeTexEnvironment':
        return WorldSource('RENDER', why="its colour comes from '%s'" % src.bl_label,
                           sun_disc=_sun_disc(src, sock))
    if sock.name != 'Color':
        return WorldSource('RENDER', why="the Background reads the Environment Texture's %s" % sock.name)
    if src.image is None:
        return WorldSource('UNIFORM', radiance=(0.0, 0.0, 0.0),
                           notes=["world '%s': the Environment Texture has no image: the world is black"
                                  % world.name])
    if src.projection != 'EQUIRECTANGULAR':
        return WorldSource('RENDER', why="the Environment Texture's projection is %s" % src.projection)
    if src.image.source not in ('FILE', 'GENERATED'):
        return WorldSource('RENDER', why="its image is a %s" % src.image.source.lower())
    if not _texture_mapping_is_identity(src):
        return WorldSource('RENDER', why="the Environment Texture has a texture mapping")
    lookup, why = _lookup_matrix(src)
    if lookup is None:
        return WorldSource('RENDER', why=why)
    space = src.image.colorspace_settings.name
    if _image_file(src.image) is None and not src.image.is_float and \
            not (compat.is_linear_colorspace(space) or space == "sRGB"):
        return WorldSource('RENDER', why="its image's colour space is %s" % space)
    notes = []
    if src.interpolation != 'Linear':
        notes.append("world '%s': the Environment Texture's %s interpolation is baked as Linear"
                     % (world.name, src.interpolation))
    # The engine's rotation takes the map's frame into the world: the lookup matrix's transpose.
    return WorldSource('IMAGE', image=src.image, rotation=lookup.T.copy(), strength=s, notes=notes)


def _sun_disc(node, socket):
    """(name, angular diameter) of a physical Sky Texture whose sun disc the Background shows as it is (its Color
    straight into the Background, its Vector not linked) and which lies wholly above the horizon
    (Cycles draws no disc below it); None otherwise. Such a sun goes to the engine as a sun lamp of
    the disc's angle beside a map rendered without it (see WorldRender)."""
    if node.bl_idname != 'ShaderNodeTexSky' or socket.name != 'Color' or node.sky_type in ('PREETHAM', 'HOSEK_WILKIE'):
        return None
    vector = node.inputs.get('Vector')
    if not getattr(node, "sun_disc", False) or (vector is not None and vector.is_linked):
        return None
    if not node.sun_elevation - 0.5 * node.sun_size > 0.0 or not node.sun_size > 0.0:
        return None
    return node.name, float(node.sun_size)


def emits(world):
    """True where the world lights the scene (a guess for a rendered one: its strength is not 0)."""
    w = describe(world)
    if w.kind == 'UNIFORM':
        return max(w.radiance) > 0.0
    if w.kind == 'IMAGE':
        return w.strength > 0.0
    return w.kind == 'RENDER'


def _image_file(image):
    """The image's file when the engine reads it as Blender does: a file on disk, not packed,
    float in a linear colour space or 8-bit sRGB. Else None."""
    if image.source != 'FILE' or image.packed_file is not None:
        return None
    path = bpy.path.abspath(image.filepath, library=image.library)
    if not path or not os.path.isfile(path):
        return None
    space = image.colorspace_settings.name
    ext = os.path.splitext(path)[1].lower()
    is_float = ext in (".exr", ".hdr", ".pfm") or (image.has_data and image.is_float)
    if is_float:
        return path if compat.is_linear_colorspace(space) else None
    depth = image.depth if image.has_data else 0
    return path if space == "sRGB" and ext in (".png", ".jpg", ".jpeg", ".tga", ".bmp") and \
        depth in (0, 24, 32) else None


def _image_pixels(image):
    """(H, W, 3) float32 linear radiance, top row first, from Blender's pixels (float images are
    linear; 8-bit ones hold their encoded values: sRGB is decoded, linear spaces kept)."""
    w, h = image.size
    space = image.colorspace_settings.name
    px = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    rgb = px.reshape(h, w, 4)[::-1, :, :3]
    if not image.is_float and space == "sRGB":  # byte pixels are the encoded values
        rgb = np.where(rgb <= 0.04045, rgb / 12.92, ((rgb + 0.055) / 1.055) ** 2.4)
    rgb = np.nan_to_num(rgb, nan=0.0, posinf=0.0, neginf=0.0)
    return np.ascontiguousarray(np.maximum(rgb, 0.0), dtype=np.float32)


class WorldRender:
    """A world being rendered into a map in a separate Blender process (world_render_child.py),
    which reads it from a library file written into a temporary folder: the user's session gains
    nothing and its Render Result keeps the last render. Started early (start()), so that the
    render runs beside the mesh export; result() waits for it."""

    def __init__(self, world, size=RENDER_SIZE, samples=RENDER_SAMPLES, sun_disc=None):
        self.size = size
        self.sun_disc = sun_disc
        self.t0 = time.perf_counter()
        self.folder = tempfile.mkdtemp(prefix="photonlm_world_")
        self.process = None
        try:
            lib = os.path.join(self.folder, "world.blend")
            self.out = os.path.join(self.folder, "world.npy")
            bpy.data.libraries.write(lib, {world}, path_remap='ABSOLUTE', fake_user=True)
            child = os.path.join(os.path.dirname(os.path.abspath(__file__)), "world_render_child.py")
            cmd = [bpy.app.binary_path, "-b", "--factory-startup", "-noaudio", "--python-exit-code", "1",
                   "--python", child, "--", lib, world.name, self.out, str(size[0]), str(size[1]), str(samples)]
            if sun_disc is not None:  # a second render, without the sun disc
                cmd.append(sun_disc[0])
            self.process = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        except BaseException:
            self.close()
            raise

    def result(self, timeout=600):
        """(map, sun): the map, (H, W, 3) float32 radiance, top row first, in Blender's
        equirectangular convention; sun None, or where the render was asked to split off a sun disc,
        the disc (split_sun; None where it is black) and the map without it. Raises RuntimeError with the
        child's message on failure. Removes the folder."""
        try:
            log, _ = self.process.communicate(timeout=timeout)
            sky = os.path.splitext(self.out)[0] + "_sky.npy"
            if self.process.returncode != 0 or not os.path.isfile(self.out) or \
                    (self.sun_disc is not None and not os.path.isfile(sky)):
                lines = [l for l in log.splitlines() if "rror" in l or "failed" in l]
                raise RuntimeError(lines[-1] if lines else "Blender exited with code %d" % self.process.returncode)
            full = np.load(self.out)
            if self.sun_disc is None:
                return full, None
            return split_sun(full, np.load(sky), self.sun_disc[1])
        finally:
            self.close()

    def seconds(self):
        return time.perf_counter() - self.t0

    def close(self):
        if self.process is not None and self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        shutil.rmtree(self.folder, ignore_errors=True)


class Sun:
    """A sun disc split off a rendered world: `direction` (unit, world, towards the sun), `irradiance`
    (RGB, on a surface facing it) and `angle` (the disc's angular diameter, radians)."""

    def __init__(self, direction, irradiance, angle):
        self.direction, self.irradiance, self.angle = direction, irradiance, angle


def pixel_directions(h, w):
    """Unit directions of an equirectangular map's pixel centres (Blender's convention: the centre
    column looks along +X, the top row is +Z) and each pixel's solid angle: ((h, w, 3), (h, 1))."""
    elev = math.pi * (0.5 - (np.arange(h) + 0.5) / h)
    azim = 2.0 * math.pi * (0.5 - (np.arange(w) + 0.5) / w)
    ce = np.cos(elev)[:, None]
    d = np.stack(np.broadcast_arrays(ce * np.cos(azim)[None, :], ce * np.sin(azim)[None, :],
                                     np.sin(elev)[:, None]), axis=-1)
    edges = math.pi * (0.5 - np.arange(h + 1) / h)
    solid = (2.0 * math.pi / w) * (np.sin(edges[:-1]) - np.sin(edges[1:]))
    return d, solid[:, None]


def split_sun(full, sky, angle):
    """(sky, Sun): the light of a sun disc as the difference of a world's renders with it (full) and
    without it (sky), both (H, W, 3) radiance: its irradiance that difference's integral over the
    pixels within the disc's radius (angle / 2) plus 2 degrees (at least 3 pixels) of its brightest
    pixel, its direction their light-weighted mean direction; None where that light is 0. The map
    that goes with it is `sky`."""
    h, w, _ = full.shape
    diff = (full.astype(np.float64) - sky).mean(axis=2)
    d, solid = pixel_directions(h, w)
    peak = d[np.unravel_index(int(np.argmax(diff)), diff.shape)]
    near = d @ peak > math.cos(0.5 * angle + max(math.radians(2.0), 3.0 * 2.0 * math.pi / w))
    weight = np.where(near[..., None], full.astype(np.float64) - sky, 0.0) * solid[..., None]
    irradiance = weight.reshape(-1, 3).sum(axis=0)
    direction = (weight.mean(axis=2)[..., None] * d).reshape(-1, 3).sum(axis=0)
    if not max(irradiance) > 0.0 or not np.linalg.norm(direction) > 0.0:  # a black sun (Sun Intensity 0)
        return sky, None
    direction /= np.linalg.norm(direction)
    return sky, Sun(direction, irradiance, angle)


def render_world(world, size=RENDER_SIZE, samples=RENDER_SAMPLES):
    """Renders the world with Cycles into an equirectangular map in Blender's convention (the
    image's centre looks along +X, its top row is +Z): (H, W, 3) float32 radiance, top row first."""
    return WorldRender(world, size, samples).result()[0]


# The last rendered world, by the fingerprint of what it depends on: bakes of an unchanged sky
# (tweaking materials, lights or objects) reuse its map instead of rendering it again.
_RENDERED = {}


def _image_key(image):
    if image.is_dirty:  # edited in memory: not comparable, render again
        return ("dirty", image.name, time.perf_counter())
    path = bpy.path.abspath(image.filepath, library=image.library) if image.filepath else ""
    mtime = os.path.getmtime(path) if path and os.path.isfile(path) else None
    packed = image.packed_file.size if image.packed_file is not None else None
    return ("image", image.name, image.source, path, mtime, packed, tuple(image.size),
            image.colorspace_settings.name, image.alpha_mode, getattr(image, "generated_type", None))


_NODE_BASE = None


def _struct_key(struct, depth=0):
    """What a node (or a node's settings struct) looks like to a render: its own properties, not
    the editor's (location, selection, size...)."""
    global _NODE_BASE
    if _NODE_BASE is None:
        _NODE_BASE = {p.identifier for p in bpy.types.Node.bl_rna.properties} - {"mute"}
    out = []
    for prop in struct.bl_rna.properties:
        ident = prop.identifier
        if ident in _NODE_BASE or ident == "rna_type" or prop.type == 'COLLECTION':
            continue
        value = getattr(struct, ident, None)
        if isinstance(value, bpy.types.Image):
            value = _image_key(value)
        elif isinstance(value, bpy.types.NodeTree):
            value = _tree_key(value, depth + 1) if depth < 8 else value.name
        elif isinstance(value, bpy.types.Object):
            value = (value.name, tuple(tuple(r) for r in value.matrix_world))
        elif isinstance(value, bpy.types.ID):
            value = (type(value).__name__, value.name)
        elif isinstance(value, bpy.types.bpy_struct):
            value = _struct_key(value, depth + 1) if depth < 8 else None
        elif hasattr(value, "__len__") and not isinstance(value, str):
            value = tuple(value)
        out.append((ident, value))
    return tuple(out)


def _tree_key(tree, depth=0):
    nodes = []
    for node in sorted(tree.nodes, key=lambda n: n.name):
        sockets = tuple((s.identifier, tuple(s.default_value) if hasattr(s.default_value, "__len__")
                         else s.default_value) if hasattr(s, "default_value") else (s.identifier,)
                        for s in node.inputs)
        nodes.append((node.name, node.bl_idname, _struct_key(node, depth), sockets))
    links = tuple(sorted((l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier,
                          l.is_muted) for l in tree.links))
    return (tuple(nodes), links)


def fingerprint(world, size=RENDER_SIZE, samples=RENDER_SAMPLES):
    """A value that changes when anything the world's render depends on changes."""
    tree = _tree_key(world.node_tree) if compat.uses_nodes(world) else None
    return (world.name, compat.use_nodes_value(world), tuple(world.color), tree, tuple(size), samples)


class PendingWorld:
    """The world as export_scene found it, its render (if any) under way or found rendered."""

    def __init__(self, world):
        self.world = world
        self.source = describe(world)
        self.render = self.key = self.cached = None
        if self.source.kind == 'RENDER':
            self.key = fingerprint(world)
            self.cached = _RENDERED.get(self.key)
            if self.cached is None:
                self.render = WorldRender(world, sun_disc=self.source.sun_disc)

    def rgb(self):
        """The rendered map and its sun (see WorldRender.result; waits for the render; kept for the
        next bake)."""
        if self.cached is None:
            self.cached = self.render.result()
            _RENDERED.clear()
            _RENDERED[self.key] = self.cached
        return self.cached

    def cancel(self):
        if self.render is not None:
            self.render.close()


def start(world):
    """Looks at the world and starts rendering it if it must be rendered (see set_world)."""
    return PendingWorld(world)


def _add_sun(plm, world, sun):
    """The sun disc split off a rendered world as a sun lamp (shining along its matrix's -Z), a uniform
    disc as wide as the limb-darkened one (LIMB_DARKENED_SUN_ANGLE); its id."""
    z = np.asarray(sun.direction, np.float64)
    x = np.cross((0.0, 0.0, 1.0) if abs(z[2]) < 0.9 else (1.0, 0.0, 0.0), z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    matrix = [[x[i], y[i], z[i], 0.0] for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]
    power = float(max(sun.irradiance))
    color = tuple(float(max(c, 0.0)) / power for c in sun.irradiance)
    return plm.add_light('SUN', name="%s (sun disc)" % world.name, color=color, power=power, matrix=matrix,
                         angle=sun.angle * LIMB_DARKENED_SUN_ANGLE)


def set_world(plm, world, reports, pending=None):
    """Gives the engine the world: uniform, an image, or rendered (waits for start()'s render). Returns
    the id of the sun lamp a rendered Sky Texture's sun disc became (it belongs to the world's light
    group), or None."""
    pending = pending if pending is not None else start(world)
    w = pending.source
    sun_light = None
    for note in w.notes:
        reports.warning(note)
    if w.kind == 'UNIFORM':
        if max(w.radiance) > 0.0:
            plm.set_world(w.radiance)
    elif w.kind == 'IMAGE' and w.strength > 0.0:
        path = _image_file(w.image)
        if path is not None:
            plm.set_world_map_file(path, rotation=w.rotation, strength=w.strength)
        else:
            plm.set_world_map(_image_pixels(w.image), rotation=w.rotation, strength=w.strength)
    elif w.kind == 'RENDER':
        r = pending.render
        try:
            rgb, sun = pending.rgb()
            plm.set_world_map(rgb)
            if sun is not None:
                sun_light = _add_sun(plm, world, sun)
            if r is None:
                reports.info("world '%s': the map rendered for the last bake is reused (%s)" % (world.name, w.why))
            else:
                reports.info("world '%s' rendered into a %d x %d map (%s%s): %.1f s"
                             % (world.name, r.size[0], r.size[1], w.why,
                                "; its sun disc a sun lamp" if sun_light is not None else "", r.seconds()))
        except (RuntimeError, OSError, subprocess.SubprocessError) as e:
            reports.warning("world '%s' could not be rendered into a map (%s): the world is left out"
                            % (world.name, e))
    return sun_light
