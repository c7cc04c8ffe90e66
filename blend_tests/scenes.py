"""Scene builders and helpers shared by the headless Blender tests and scripts/demo_bake.py.

Everything is built from scratch in Python (no .blend files). Lightmap UVs are laid out
explicitly (texel-aligned rectangles, uniform texel density inside each object), so the
layout is the same in every Blender process and no texel straddles two faces.
"""
import json
import math
import os
import shutil
import subprocess
import sys
import time

import bpy
import numpy as np
from mathutils import Vector


# ---- Blender versions: every difference between 3.4, 4.x and 5.x the tests meet lives here --------------

BLENDER = tuple(bpy.app.version[:2])

# Principled BSDF v2 (Blender 4.0+) renamed the inputs the tests set; the keys are 3.4's names.
_PRINCIPLED_V2_NAMES = {
    "Specular": "Specular IOR Level",      # 0.5 = F0 0.04 in both; 0 = no specular layer in both
    "Transmission": "Transmission Weight",
    "Clearcoat": "Coat Weight",
    "Clearcoat Roughness": "Coat Roughness",
    "Sheen": "Sheen Weight",
    "Subsurface": "Subsurface Weight",
    "Emission": "Emission Color",
}
PRINCIPLED_V2 = BLENDER >= (4, 0)


def principled_input(bsdf, name):
    """The Principled BSDF input that 3.4 calls `name`, in this Blender (v2 names from 4.0)."""
    if PRINCIPLED_V2 and name in _PRINCIPLED_V2_NAMES:
        name = _PRINCIPLED_V2_NAMES[name]
    return bsdf.inputs[name]


def node_material(name):
    """A new material with a node tree (Principled BSDF into Material Output). 5.0 made node
    trees the only kind of material and deprecated Material.use_nodes."""
    mat = bpy.data.materials.new(name)
    if BLENDER < (5, 0):
        mat.use_nodes = True
    return mat


def node_world(name):
    """A new world with a node tree (Background into World Output); see node_material."""
    world = bpy.data.worlds.new(name)
    if BLENDER < (5, 0):
        world.use_nodes = True
    return world


def eevee_engine():
    """EEVEE's render engine id: 'BLENDER_EEVEE_NEXT' in 4.2 to 4.4, 'BLENDER_EEVEE' before and after."""
    return 'BLENDER_EEVEE_NEXT' if (4, 2) <= BLENDER < (5, 0) else 'BLENDER_EEVEE'


def see_through_in_eevee(mat):
    """EEVEE draws `mat` (glass) blended, refracting the scene behind it, without back faces."""
    if hasattr(mat, "surface_render_method"):   # EEVEE Next (4.2+)
        mat.surface_render_method = 'BLENDED'
        mat.use_raytrace_refraction = True
        mat.use_transparency_overlap = False
    else:
        mat.blend_method = 'BLEND'
        mat.use_screen_refraction = True
        mat.show_transparent_back = False


def group_socket(group, in_out, socket_type, name):
    """Add an input ('INPUT') or output ('OUTPUT') socket to a node group (4.0: group.interface)."""
    if hasattr(group, "interface"):
        return group.interface.new_socket(name, in_out=in_out, socket_type=socket_type)
    return (group.inputs if in_out == 'INPUT' else group.outputs).new(socket_type, name)


def mix_color_node(nt):
    """A colour Mix node (Mix, RGBA) and its sockets: (node, fac, a, b, result). Blender 3.4 has
    it beside the legacy MixRGB; sockets are taken by index (its A and B exist once per type)."""
    mix = nt.nodes.new('ShaderNodeMix')
    mix.data_type = 'RGBA'
    return mix, mix.inputs[0], mix.inputs[6], mix.inputs[7], mix.outputs[2]


def set_edge_crease(mesh, edge_index, value):
    """Subdivision crease of one edge (MeshEdge.crease before 4.0, the 'crease_edge' attribute after)."""
    if BLENDER < (4, 0):
        mesh.edges[edge_index].crease = value
        return
    attr = mesh.attributes.get("crease_edge") or mesh.attributes.new("crease_edge", 'FLOAT', 'EDGE')
    attr.data[edge_index].value = value


def physical_sky_type():
    """The Sky Texture's single-scattering physical model: 'NISHITA' until 4.x, 'SINGLE_SCATTERING'
    from 5.0 (which added a multiple-scattering model as the default)."""
    return 'NISHITA' if BLENDER < (5, 0) else 'SINGLE_SCATTERING'


def setup_paths():
    """Put $PHOTONLM_SOURCE_DIR/addon and /python_bridge on sys.path, register the add-on."""
    src = os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    for sub in ("addon", "python_bridge"):
        p = os.path.join(src, sub)
        if p not in sys.path:
            sys.path.insert(0, p)
    import photonlm_blender
    if not hasattr(bpy.types.Scene, "photonlm"):
        photonlm_blender.register()
    return photonlm_blender


def enable_gltf_addons():
    """Blender's glTF exporter finds PhotonLM's hook among enabled add-ons: enable both as
    Preferences does (the add-on from $PHOTONLM_SOURCE_DIR/addon, as setup_paths puts it)."""
    import addon_utils
    src = os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    for sub in ("addon", "python_bridge"):
        p = os.path.join(src, sub)
        if p not in sys.path:
            sys.path.insert(0, p)
    addon_utils.enable("io_scene_gltf2", default_set=True)
    addon_utils.enable("photonlm_blender", default_set=True, handle_error=lambda e: print("ENABLE ERROR", e))
    return setup_paths()


def render_lightmap_preview(path, width, height):
    """Render the scene to `path` in its render file format as the lightmap preview shows it: EEVEE
    (16 samples), the Standard view transform, the world black and the lights off (the preview is
    emission: the light is the lightmap's)."""
    scene = bpy.context.scene
    r = scene.render
    r.engine = eevee_engine()
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    r.film_transparent = False
    scene.eevee.taa_render_samples = 16
    vs = scene.view_settings
    vs.view_transform, vs.look, vs.exposure, vs.gamma = 'Standard', 'None', 0.0, 1.0
    scene.display_settings.display_device = 'sRGB'
    if scene.world is not None and scene.world.use_nodes:
        scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    for obj in scene.objects:
        if obj.type == 'LIGHT':
            obj.hide_render = True
    scene.photonlm.preview_mode = 'LIGHTMAP'
    r.filepath = path
    bpy.ops.render.render(write_still=True)


def principled_materials():
    """Every mesh object's Diffuse BSDF material swapped for a Principled BSDF of its colour (what
    Blender's glTF exporter writes as a base colour)."""
    for obj in bpy.context.scene.objects:
        if obj.type != 'MESH':
            continue
        for slot in obj.material_slots:
            old = slot.material
            diffuse = [n for n in old.node_tree.nodes if n.bl_idname == 'ShaderNodeBsdfDiffuse']
            if diffuse:
                color = tuple(diffuse[0].inputs["Color"].default_value)[:3]
                slot.material = diffuse_material(old.name + "_principled", color, principled=True)


def out_dir(name):
    base = os.environ.get("PHOTONLM_TEST_OUT") or os.path.join("/tmp", "photonlm_test_out")
    d = os.path.join(base, name)
    os.makedirs(d, exist_ok=True)
    return d


def exr_rgb(path):
    """An EXR's RGB as Blender reads it: (h, w, 3) float32, row 0 = bottom (as the engine's
    lightmap arrays)."""
    image = bpy.data.images.load(path, check_existing=False)
    try:
        w, h = image.size
        px = np.empty(w * h * 4, np.float32)
        image.pixels.foreach_get(px)
        return px.reshape(h, w, 4)[..., :3].copy()
    finally:
        bpy.data.images.remove(image)


def cli_path():
    """The photonlm CLI: $PHOTONLM_CLI if set (a self-contained copy, for Blenders in other Debian
    roots), else the one built beside PHOTONLM_LIBRARY (build/bin beside build/lib)."""
    if os.environ.get("PHOTONLM_CLI"):
        return os.environ["PHOTONLM_CLI"]
    lib = os.environ.get("PHOTONLM_LIBRARY", "")
    return os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(lib)), "..", "bin", "photonlm"))


def clear_scene():
    """Remove every object, mesh, material, light, image and world; set a black world."""
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.lights,
                 bpy.data.images, bpy.data.cameras, bpy.data.worlds):
        for item in list(coll):
            coll.remove(item)
    scene = bpy.context.scene
    world = node_world("World")
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    scene.world = world
    return scene


# ---- materials --------------------------------------------------------------------------------

def diffuse_material(name, color, principled=False):
    mat = node_material(name)
    nt = mat.node_tree
    nodes = nt.nodes
    out = nodes["Material Output"]
    if principled:
        bsdf = nodes["Principled BSDF"]
        bsdf.inputs["Base Color"].default_value = tuple(color) + (1.0,)
        principled_input(bsdf, "Specular").default_value = 0.0
        bsdf.inputs["Roughness"].default_value = 1.0
    else:
        nodes.remove(nodes["Principled BSDF"])
        bsdf = nodes.new("ShaderNodeBsdfDiffuse")
        bsdf.inputs["Color"].default_value = tuple(color) + (1.0,)
        bsdf.inputs["Roughness"].default_value = 0.0
        nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
    bsdf.location = (-300, 0)
    return mat


def emission_material(name, color, strength):
    mat = node_material(name)
    nt = mat.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = tuple(color) + (1.0,)
    em.inputs["Strength"].default_value = strength
    nt.links.new(em.outputs[0], nt.nodes["Material Output"].inputs["Surface"])
    return mat


# ---- meshes with fixed lightmap UVs ----------------------------------------------------------------

def quads_object(name, quads, material, resolution):
    """A mesh object from quads [(p0, p1, p2, p3, uv_rect)], uv_rect = (u0, v0, u1, v1) in [0, 1].
    Corners are counter-clockwise seen from the front (normal = (p1-p0) x (p3-p0)). The UV map
    'lightmap' maps p0->(u0,v0), p1->(u1,v0), p2->(u1,v1), p3->(u0,v1); a second map 'UVMap'
    holds the same values (a stand-in for the artist's texture UVs)."""
    verts, faces, uvs = [], [], []
    for (p0, p1, p2, p3, (u0, v0, u1, v1)) in quads:
        base = len(verts)
        verts += [tuple(p0), tuple(p1), tuple(p2), tuple(p3)]
        faces.append((base, base + 1, base + 2, base + 3))
        uvs += [(u0, v0), (u1, v0), (u1, v1), (u0, v1)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.update()
    tex = mesh.uv_layers.new(name="UVMap")
    lm = mesh.uv_layers.new(name="lightmap")
    flat = np.array(uvs, np.float32).ravel()
    tex.data.foreach_set("uv", flat)
    lm.data.foreach_set("uv", flat)
    mesh.uv_layers.active = tex
    tex.active_render = True
    if material is not None:
        mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.photonlm.resolution = resolution
    return obj


def plane(name, material, size=2.0, z=0.0, resolution=16):
    h = size / 2
    return quads_object(name, [((-h, -h, z), (h, -h, z), (h, h, z), (-h, h, z), (0, 0, 1, 1))],
                        material, resolution)


def box_quads(center, half_x, half_y, height, angle, texel, res):
    """Five faces (no bottom) of a box standing on z=0, rotated by `angle` about z, with a
    texel-aligned lightmap layout of uniform density (`texel` metres per texel, res x res map).
    Sides are laid out in a row, the top above the first side."""
    c, s = math.cos(angle), math.sin(angle)

    def world(p):
        return (center[0] + c * p[0] - s * p[1], center[1] + s * p[0] + c * p[1], p[2])

    hx, hy, h = half_x, half_y, height
    faces = [  # p0, u edge, v edge (u x v = outward normal)
        ((hx, -hy, 0), (0, 2 * hy, 0), (0, 0, h)),
        ((hx, hy, 0), (-2 * hx, 0, 0), (0, 0, h)),
        ((-hx, hy, 0), (0, -2 * hy, 0), (0, 0, h)),
        ((-hx, -hy, 0), (2 * hx, 0, 0), (0, 0, h)),
        ((-hx, -hy, h), (2 * hx, 0, 0), (0, 2 * hy, 0)),
    ]
    quads = []
    x = 1
    for i, (p0, u, v) in enumerate(faces):
        nu = round(math.sqrt(sum(a * a for a in u)) / texel)
        nv = round(math.sqrt(sum(a * a for a in v)) / texel)
        if i < 4:
            cx, cy = x, 1
            x += nu + 1
        else:
            cx, cy = 1, 1 + round(h / texel) + 1
        assert cx + nu <= res and cy + nv <= res, "box layout does not fit"
        p0v, uv_, vv = Vector(p0), Vector(u), Vector(v)
        pts = [p0v, p0v + uv_, p0v + uv_ + vv, p0v + vv]
        quads.append(tuple(world(p) for p in pts) + ((cx / res, cy / res, (cx + nu) / res, (cy + nv) / res),))
    return quads


# ---- Cornell box ----------------------------------------------------------------------------------

CORNELL_OBJECTS = ("floor", "ceiling", "back", "left", "right", "short_box", "tall_box")
CORNELL_ALBEDO = {"white": (0.73, 0.73, 0.73), "red": (0.63, 0.065, 0.05), "green": (0.14, 0.45, 0.09)}


def cornell_box(resolution=32, light_power=40.0):
    """A 2 m Cornell box (x, y in [-1, 1], z in [0, 2], open towards -y), a 0.5 m square area
    light under the ceiling, two boxes. Every object has its own Diffuse BSDF material and a
    fixed, texel-aligned lightmap layout. Returns {name: object} plus 'light'."""
    objs = {}

    def mat(name, kind):
        return diffuse_material(name, CORNELL_ALBEDO[kind])

    walls = {
        "floor": (((-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)), "white"),
        "ceiling": (((-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)), "white"),
        "back": (((-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)), "white"),
        "left": (((-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)), "red"),
        "right": (((1, 1, 0), (1, -1, 0), (1, -1, 2), (1, 1, 2)), "green"),
    }
    for name, (pts, kind) in walls.items():
        objs[name] = quads_object(name, [pts + ((0, 0, 1, 1),)], mat("mat_" + name, kind), resolution)
    texel = 3.2 / resolution  # 0.1 m at 32 x 32: the box layouts fit with room to spare
    objs["short_box"] = quads_object(
        "short_box", box_quads((0.35, -0.3), 0.3, 0.3, 0.6, math.radians(-17), texel, resolution),
        mat("mat_short_box", "white"), resolution)
    objs["tall_box"] = quads_object(
        "tall_box", box_quads((-0.35, 0.35), 0.3, 0.3, 1.2, math.radians(20), texel, resolution),
        mat("mat_tall_box", "white"), resolution)
    light_data = bpy.data.lights.new("ceiling_light", 'AREA')
    light_data.shape = 'SQUARE'
    light_data.size = 0.5
    light_data.energy = light_power
    light = bpy.data.objects.new("ceiling_light", light_data)
    light.location = (0.0, 0.0, 1.98)
    bpy.context.scene.collection.objects.link(light)
    objs["light"] = light
    return objs


def cornell_camera():
    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens = 38.0
    cam = bpy.data.objects.new("camera", cam_data)
    cam.location = (0.0, -3.9, 1.0)
    cam.rotation_euler = (math.radians(90), 0, 0)
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    return cam


# ---- lights --------------------------------------------------------------------------------------------

def add_light(name, kind, location, rotation=(0, 0, 0), **settings):
    data = bpy.data.lights.new(name, kind)
    for k, v in settings.items():
        setattr(data, k, v)
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    obj.rotation_euler = rotation
    bpy.context.scene.collection.objects.link(obj)
    return obj


def set_world_color(color, strength=1.0):
    bg = bpy.context.scene.world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = tuple(color) + (1.0,)
    bg.inputs["Strength"].default_value = strength


# ---- baking -------------------------------------------------------------------------------------------------

def photonlm_bake(photons, max_bounces, seed=1, target_error=0.02, **settings):
    """Bake with the add-on's operator (the path an artist uses). Returns photonlm_blender.record.last()
    with the operator's wall time added. photons is the cap when target_error > 0 (the add-on's
    default 0.02), the exact count at 0; settings: other scene.photonlm settings to set first."""
    from photonlm_blender.writeback import record
    s = bpy.context.scene.photonlm
    s.photons = photons
    s.target_error = target_error
    s.max_bounces = max_bounces
    s.seed = seed
    for key, value in settings.items():
        setattr(s, key, value)
    t0 = time.perf_counter()
    res = bpy.ops.photonlm.bake()
    wall = time.perf_counter() - t0
    if res != {'FINISHED'}:
        raise RuntimeError("photonlm bake returned %s" % res)
    last = record.last()
    last["wall_seconds"] = wall
    return last


def cycles_bake(objects, resolution, pass_filter, samples, bounces=32, seed=0, supersample=1):
    """Cycles DIFFUSE bake (no COLOR: irradiance / pi) of each object's single material into a
    float image through the 'lightmap' UV map. resolution: texels per side, or None for each
    object's photonlm.resolution. supersample = k bakes k x k texels per lightmap texel and
    box-averages them (a texel-average reference: a Cycles 3.4 bake texel is the average over the
    texel's central 0.5 x 0.5 square, not over the whole texel, which shows at hard edges; 4.3's is
    too, 5.2's is the whole-texel average: test_world_maps' sun-shadow edges match photonlm's Texel
    Average there). Returns ({name: (h, w, 3)}, seconds)."""
    scene = bpy.context.scene
    scene.render.engine = 'CYCLES'
    c = scene.cycles
    c.device = 'CPU'
    c.samples = samples
    c.use_adaptive_sampling = False
    c.use_denoising = False
    for k in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces"):
        setattr(c, k, bounces)
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0  # Filter Glossy (default 1) roughens glass and mirrors after a diffuse bounce: a bias
    c.seed = seed
    c.use_animated_seed = False
    # A box filter one texel wide (Cycles' default Blackman-Harris 1.5 px filter blurs sharp
    # edges across texels).
    c.pixel_filter_type = 'BOX'
    c.filter_width = 1.0
    scene.render.bake.margin = 0
    images, nodes = {}, []
    for obj in objects:
        res = (resolution or obj.photonlm.resolution) * supersample
        img = bpy.data.images.new("cycles_" + obj.name, res, res, alpha=True, float_buffer=True)
        images[obj.name] = (img, res)
        for slot in obj.material_slots:
            nt = slot.material.node_tree
            node = nt.nodes.new("ShaderNodeTexImage")
            node.image = img
            node.select = True
            nt.nodes.active = node
            nodes.append((nt, node))
    vl = bpy.context.view_layer
    vl.update()  # creates the view layer bases of newly linked objects (else: "No valid selected objects")
    names = {o.name for o in objects}
    for o in vl.objects:
        o.select_set(o.name in names)
    vl.objects.active = objects[0]
    vl.update()
    t0 = time.perf_counter()
    bpy.ops.object.bake(type='DIFFUSE', pass_filter=set(pass_filter), use_clear=True, margin=0,
                        uv_layer="lightmap", target='IMAGE_TEXTURES')
    seconds = time.perf_counter() - t0
    for nt, node in nodes:
        nt.nodes.remove(node)
    out = {}
    for name, (img, res) in images.items():
        px = np.empty(res * res * 4, np.float32)
        img.pixels.foreach_get(px)
        rgb = px.reshape(res, res, 4)[..., :3]
        r = res // supersample
        out[name] = rgb.copy() if supersample == 1 else \
            rgb.astype(np.float64).reshape(r, supersample, r, supersample, 3).mean(axis=(1, 3))
        bpy.data.images.remove(img)
    for o in vl.objects:
        o.select_set(False)
    return out, seconds


def mean_relative_error(ours, ref, mask):
    """mean(|ours - ref|) / mean(ref) over the texels in mask, all channels together."""
    a, b = ours[mask], ref[mask]
    return float(np.mean(np.abs(a - b)) / max(np.mean(b), 1e-30))


class Checks:
    """Collects pass/fail lines; raise at the end so Blender exits non-zero."""

    def __init__(self, name):
        self.name = name
        self.failed = []
        self.count = 0

    def check(self, ok, text):
        self.count += 1
        print("[%s] %s: %s" % ("PASS" if ok else "FAIL", self.name, text), flush=True)
        if not ok:
            self.failed.append(text)
        return ok

    def finish(self):
        print("%s: %d checks, %d failed" % (self.name, self.count, len(self.failed)), flush=True)
        if self.failed:
            raise AssertionError("%s FAILED: %s" % (self.name, "; ".join(self.failed)))


def layout_coverage(obj, res, sub=8):
    """Fraction of each texel of a res x res map covered by obj's 'lightmap' UV triangles
    (supersampled sub x sub per texel; exact for texel-aligned layouts). Row 0 = v near 0."""
    mesh = obj.data
    mesh.calc_loop_triangles()
    nt = len(mesh.loop_triangles)
    loops = np.empty(nt * 3, np.int32)
    mesh.loop_triangles.foreach_get("loops", loops)
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers["lightmap"].data.foreach_get("uv", uv)
    return uv_coverage(uv.reshape(-1, 2)[loops].reshape(nt, 3, 2), res, sub)


def uv_coverage(uv, res, sub=8):
    """Fraction of each texel of a res x res map covered by the UV triangles uv (T, 3, 2),
    supersampled sub x sub per texel at the sub-texels' centres; row 0 = v near 0. Each triangle is
    rasterised over its own bounding box only."""
    n = res * sub
    inside = np.zeros((n, n), bool)
    tri = uv.astype(np.float64) * n - 0.5  # fine-grid coordinates: sample k sits at k
    lo = np.clip(np.floor(tri.min(axis=1)).astype(int), 0, n - 1)
    hi = np.clip(np.ceil(tri.max(axis=1)).astype(int), 0, n - 1)
    for (a, b, c), (x0, y0), (x1, y1) in zip(tri, lo, hi):
        ys, xs = np.mgrid[y0:y1 + 1, x0:x1 + 1]

        def edge(p, q):
            return (q[0] - p[0]) * (ys - p[1]) - (q[1] - p[1]) * (xs - p[0])
        e0, e1, e2 = edge(a, b), edge(b, c), edge(c, a)
        inside[y0:y1 + 1, x0:x1 + 1] |= ((e0 >= 0) & (e1 >= 0) & (e2 >= 0)) | ((e0 <= 0) & (e1 <= 0) & (e2 <= 0))
    return inside.reshape(res, sub, res, sub).mean(axis=(1, 3))


def coverage_weighted_mean(rgb, coverage):
    """Per-object mean of a lightmap, weighted by texel coverage: with a uniform texel density
    inside the object this is the area-weighted mean of irradiance / pi over its surface."""
    w = coverage[..., None]
    return (rgb * w).sum(axis=(0, 1)) / max(float(coverage.sum()), 1e-30)


# ---- an artist's room: modifiers everywhere, automatic lightmap UVs ---------------------------------

ARTIST_ROOM_OBJECTS = ("Walls", "Floor", "Books", "Bench", "Cabinet", "Suzanne", "Ball", "SideTable")


def _bmesh_object(name, build, material):
    """A mesh object from a function that fills a bmesh (with a default 'UVMap' like Blender's
    primitives have); linked to the scene."""
    import bmesh
    bm = bmesh.new()
    build(bm)
    mesh = bpy.data.meshes.new(name)
    bm.to_mesh(mesh)
    bm.free()
    mesh.uv_layers.new(name="UVMap")
    if material is not None:
        mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _box(bm, lo, hi, skip=()):
    """Add an axis-aligned box lo..hi to a bmesh, faces outward; `skip` names faces to leave out
    ('-x', '+x', '-y', '+y', '-z', '+z')."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [bm.verts.new(p) for p in ((x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0),
                                   (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1))]
    faces = {'-z': (0, 3, 2, 1), '+z': (4, 5, 6, 7), '-y': (0, 1, 5, 4), '+y': (2, 3, 7, 6),
             '-x': (3, 0, 4, 7), '+x': (1, 2, 6, 5)}
    for key, idx in faces.items():
        if key not in skip:
            bm.faces.new([v[i] for i in idx])


def write_texture_png(path, size=64):
    """A small wood-plank-like PNG (8-bit sRGB) for the floor's image texture."""
    img = bpy.data.images.new("floor_planks_src", size, size, alpha=False)
    y, x = np.mgrid[0:size, 0:size]
    plank = (y // (size // 4)) % 2
    grain = 0.04 * np.sin(x * 0.7 + 3.0 * plank) + 0.03 * ((x + 7 * plank) % (size // 2) == 0)
    base = np.where(plank[..., None] == 1, [0.55, 0.36, 0.2], [0.62, 0.42, 0.24])
    rgb = np.clip(base - grain[..., None], 0, 1)
    px = np.concatenate([rgb, np.ones((size, size, 1))], axis=2).astype(np.float32)
    img.pixels.foreach_set(px.ravel())
    img.filepath_raw = path
    img.file_format = 'PNG'
    img.save()
    bpy.data.images.remove(img)
    return path


def textured_material(name, image_path):
    """Principled BSDF whose Base Color is an Image Texture on the mesh's 'UVMap'."""
    mat = node_material(name)
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    principled_input(bsdf, "Specular").default_value = 0.2
    bsdf.inputs["Roughness"].default_value = 0.8
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = bpy.data.images.load(image_path, check_existing=True)
    tex.location = (-600, 200)
    uv = nt.nodes.new("ShaderNodeUVMap")
    uv.uv_map = "UVMap"
    uv.location = (-850, 200)
    nt.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def artist_room(texture_dir):
    """A room the way artists build one, every object with its own material and no 'lightmap' UV
    map of its own (the add-on makes them):
      Walls      a box (4 walls and a ceiling, 6 x 5 x 3 m inside) with Solidify (0.2 m, outwards)
                 and a Boolean window (1.6 x 1.2 m) cut by 'WindowCutter' (hidden from render)
                 into the +x wall, which the sun shines on;
      Floor      a plane with an image texture (a PNG written to texture_dir) on a Principled BSDF;
      Books      one book with an Array modifier (10 books) on the cabinet;
      Bench      half a bench with a Mirror modifier (merged at x = 0);
      Cabinet    a box with a Bevel modifier;
      Suzanne    smooth-shaded, Subdivision Surface level 2 as its last modifier;
      Ball       a smooth-shaded UV sphere;
      SideTable  a table top and four legs with a Boolean hole cut by 'HoleCutter' (hidden).
    A sun shines in through the window; the world is a uniform sky colour. Returns {name: object}."""
    objs = {}
    white = diffuse_material("mat_walls", (0.8, 0.8, 0.78), principled=True)

    def walls(bm):
        _box(bm, (-3, -2.5, 0), (3, 2.5, 3), skip=('-z',))
    objs["Walls"] = w = _bmesh_object("Walls", walls, white)
    sol = w.modifiers.new("Solidify", 'SOLIDIFY')
    sol.thickness = 0.2
    sol.offset = 1.0  # outwards: the inside stays 6 x 5 x 3 m
    sol.use_even_offset = True
    cutter = _bmesh_object("WindowCutter", lambda bm: _box(bm, (2.7, -0.8, 0.9), (3.5, 0.8, 2.1)), None)
    cutter.hide_render = True
    cutter.display_type = 'WIRE'
    cut = w.modifiers.new("Window", 'BOOLEAN')
    cut.operation = 'DIFFERENCE'
    cut.object = cutter
    objs["WindowCutter"] = cutter

    png = write_texture_png(os.path.join(texture_dir, "floor_planks.png"))

    def floor(bm):
        v = [bm.verts.new(p) for p in ((-3, -2.5, 0), (3, -2.5, 0), (3, 2.5, 0), (-3, 2.5, 0))]
        bm.faces.new(v)
    objs["Floor"] = f = _bmesh_object("Floor", floor, textured_material("mat_floor", png))
    uv = np.array([(0, 0), (6, 0), (6, 5), (0, 5)], np.float32) / 2.0  # planks 2 m per tile
    f.data.uv_layers["UVMap"].data.foreach_set("uv", uv.ravel())

    objs["Books"] = b = _bmesh_object("Books", lambda bm: _box(bm, (0, 0, 0), (0.05, 0.22, 0.3)),
                                      diffuse_material("mat_books", (0.5, 0.15, 0.12)))
    b.location = (-2.45, 2.1, 0.8)
    arr = b.modifiers.new("Array", 'ARRAY')
    arr.count = 10
    arr.relative_offset_displace = (1.6, 0, 0)

    def bench(bm):
        _box(bm, (0, -0.2, 0.4), (0.7, 0.2, 0.46), skip=('-x',))
        _box(bm, (0.55, -0.15, 0.0), (0.63, 0.15, 0.4), skip=('+z',))
    objs["Bench"] = be = _bmesh_object("Bench", bench, diffuse_material("mat_bench", (0.45, 0.3, 0.2)))
    be.location = (0.0, 1.8, 0.0)
    mir = be.modifiers.new("Mirror", 'MIRROR')
    mir.use_mirror_merge = True
    mir.use_clip = True

    objs["Cabinet"] = c = _bmesh_object("Cabinet", lambda bm: _box(bm, (-0.6, -0.2, 0), (0.6, 0.2, 0.8)),
                                        diffuse_material("mat_cabinet", (0.3, 0.45, 0.6)))
    c.location = (-1.9, 2.25, 0.0)
    bev = c.modifiers.new("Bevel", 'BEVEL')
    bev.width = 0.03
    bev.segments = 3

    bpy.ops.mesh.primitive_monkey_add(size=0.7, location=(1.6, 0.9, 0.3), rotation=(0, 0, math.radians(150)))
    s = bpy.context.active_object
    s.name = "Suzanne"
    s.data.name = "Suzanne"
    s.data.polygons.foreach_set("use_smooth", np.ones(len(s.data.polygons), bool))
    s.data.materials.append(diffuse_material("mat_suzanne", (0.75, 0.6, 0.2)))
    sub = s.modifiers.new("Subdivision", 'SUBSURF')
    sub.levels = 2
    sub.render_levels = 2
    bpy.context.view_layer.update()
    ev = s.evaluated_get(bpy.context.evaluated_depsgraph_get())
    lowest = min((ev.matrix_world @ v.co).z for v in ev.data.vertices)
    s.location.z -= lowest - 0.002  # resting on the floor
    objs["Suzanne"] = s

    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, location=(-0.6, -1.4, 0.3))
    ball = bpy.context.active_object
    ball.name = "Ball"
    ball.data.polygons.foreach_set("use_smooth", np.ones(len(ball.data.polygons), bool))
    ball.data.materials.append(diffuse_material("mat_ball", (0.7, 0.7, 0.7)))
    objs["Ball"] = ball

    def table(bm):
        _box(bm, (-0.35, -0.35, 0.55), (0.35, 0.35, 0.6))
        for sx in (-1, 1):
            for sy in (-1, 1):
                x, y = 0.28 * sx, 0.28 * sy
                _box(bm, (x - 0.03, y - 0.03, 0.0), (x + 0.03, y + 0.03, 0.55), skip=('+z',))
    objs["SideTable"] = t = _bmesh_object("SideTable", table, diffuse_material("mat_table", (0.55, 0.5, 0.45)))
    t.location = (1.0, -1.2, 0.0)
    bpy.ops.mesh.primitive_cylinder_add(radius=0.06, depth=0.4, location=(1.0, -1.2, 0.58))
    hole = bpy.context.active_object
    hole.name = "HoleCutter"
    hole.hide_render = True
    hole.display_type = 'WIRE'
    tb = t.modifiers.new("Hole", 'BOOLEAN')
    tb.operation = 'DIFFERENCE'
    tb.object = hole
    objs["HoleCutter"] = hole

    add_light("Sun", 'SUN', (6, -1, 5), rotation=(math.radians(50), 0, math.radians(100)), energy=4.0,
              angle=math.radians(2.0))
    set_world_color((0.35, 0.45, 0.65), 1.0)
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    bpy.context.view_layer.update()
    return objs


def evaluated_lightmap_triangles(obj, uv_name="lightmap", world=True):
    """World (or, world=False, object-space) positions (T, 3, 3) and `uv_name` UVs (T, 3, 2) of
    obj's evaluated mesh (None without that UV map)."""
    dg = bpy.context.evaluated_depsgraph_get()
    ev = obj.evaluated_get(dg)
    me = ev.to_mesh()
    try:
        me.calc_loop_triangles()
        nt = len(me.loop_triangles)
        co = np.empty(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        pos = co.reshape(-1, 3)
        if world:
            m = np.array(ev.matrix_world, np.float64)
            pos = pos @ m[:3, :3].T + m[:3, 3]
        tv = np.empty(nt * 3, np.int32)
        me.loop_triangles.foreach_get("vertices", tv)
        tl = np.empty(nt * 3, np.int32)
        me.loop_triangles.foreach_get("loops", tl)
        layer = me.uv_layers.get(uv_name)
        uv = None
        if layer is not None:
            a = np.empty(len(me.loops) * 2, np.float32)
            layer.data.foreach_get("uv", a)
            uv = a.reshape(-1, 2)[tl].reshape(nt, 3, 2)
        return pos[tv].reshape(nt, 3, 3), uv
    finally:
        ev.to_mesh_clear()


# ---- Tests that need a window (the modal operator) -------------------------------------------

WINDOWED_RESULT = "PHOTONLM_WINDOWED_RESULT"  # set in the windowed child: where its JSON result goes


def is_windowed_child():
    return bool(os.environ.get(WINDOWED_RESULT))


def write_windowed_result(result, quit=True):
    """In the windowed child: hand `result` (a JSON-able dict) to the parent, then quit Blender."""
    with open(os.environ[WINDOWED_RESULT], "w") as f:
        json.dump(result, f)
    if quit:
        bpy.ops.wm.quit_blender()


def view3d_override():
    """Context override for operators that need the window's 3D viewport (the modal bake)."""
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == 'VIEW_3D')
    return dict(window=win, screen=win.screen, area=area)


def run_windowed(checks, name, script, timeout):
    """Re-run `script` in a windowed Blender under xvfb-run and return the dict its child wrote
    (write_windowed_result), or None where xvfb-run is missing (printed as SKIP). A child that
    failed or wrote nothing fails the checks and ends the test."""
    xvfb = shutil.which("xvfb-run")
    if xvfb is None:
        print("SKIP %s: xvfb-run not found (the modal path needs a window)" % name)
        return None
    result_path = os.path.join(out_dir(name), name + "_result.json")
    if os.path.exists(result_path):
        os.remove(result_path)
    env = dict(os.environ, **{WINDOWED_RESULT: result_path})
    cmd = [xvfb, "-a", "-s", "-screen 0 1280x800x24", bpy.app.binary_path, "--factory-startup",
           "--python", os.path.abspath(script)]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=timeout)
        text, code = proc.stdout.decode("utf-8", "replace"), proc.returncode
    except subprocess.TimeoutExpired as e:
        text, code = (e.stdout or b"").decode("utf-8", "replace"), -1
    print("\n".join(l for l in text.splitlines() if "PhotonLM" in l or "CHILD" in l))
    ran = os.path.exists(result_path)
    r = json.load(open(result_path)) if ran else {}
    if not checks.check(ran and "error" not in r, "windowed Blender ran (%.1f s, exit %d) %s"
                        % (time.perf_counter() - t0, code, r.get("error", ""))):
        print(text[-4000:])
        checks.finish()
    return r


LIGHT_GROUPS_ROOM = ("floor", "ceiling", "wall_window", "wall_back", "wall_left", "wall_right")


def light_groups_room(res, sky):
    """A 4 x 4 x 2.5 m room with a 1.6 x 1 m window in its -x wall (six objects, each its own
    diffuse material, res x res lightmaps), a sun through the window and a uniform sky (`sky`
    x 2) in Blender's Light Group "day", a point and an area lamp in "night", and a camera at the
    back wall looking at the window. Returns (scene, sun, lamp, panel)."""
    scene = clear_scene()
    grey = (0.7, 0.7, 0.7)
    uv = (0, 0, 1, 1)

    def wall(name, quads, colour=grey):
        return quads_object(name, quads, diffuse_material("mat_" + name, colour), res)
    wall("floor", [((-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0), uv)], (0.6, 0.5, 0.4))
    wall("ceiling", [((-2, -2, 2.5), (-2, 2, 2.5), (2, 2, 2.5), (2, -2, 2.5), uv)])
    wall("wall_back", [((2, 2, 0), (2, -2, 0), (2, -2, 2.5), (2, 2, 2.5), uv)])
    wall("wall_left", [((-2, 2, 0), (2, 2, 0), (2, 2, 2.5), (-2, 2, 2.5), uv)], (0.3, 0.6, 0.3))
    wall("wall_right", [((2, -2, 0), (-2, -2, 0), (-2, -2, 2.5), (2, -2, 2.5), uv)])

    def piece(y0, y1, z0, z1):  # x = -2, u along +y, v along +z (normal +x), UVs by position
        r = ((y0 + 2) / 4, z0 / 2.5, (y1 + 2) / 4, z1 / 2.5)
        return ((-2, y0, z0), (-2, y1, z0), (-2, y1, z1), (-2, y0, z1), r)
    wall("wall_window", [piece(-2, 2, 0, 0.8), piece(-2, 2, 1.8, 2.5), piece(-2, -0.8, 0.8, 1.8),
                         piece(0.8, 2, 0.8, 1.8)])
    sun = add_light("sun", 'SUN', (-4, 0, 3), (0, math.radians(-50), 0), energy=8.0, angle=0.05)
    set_world_color(sky, 2.0)
    lamp = add_light("lamp", 'POINT', (0.5, 1.0, 2.0), energy=60.0, shadow_soft_size=0.1)
    panel = add_light("panel", 'AREA', (0.8, -1.0, 2.45), energy=40.0, size=0.6)
    cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
    cam.data.lens = 16.0
    cam.location = (1.9, 0.3, 1.4)
    cam.rotation_euler = (math.radians(78), 0, math.radians(90))
    scene.collection.objects.link(cam)
    scene.camera = cam
    vl = bpy.context.view_layer
    for name in ("day", "night"):
        vl.lightgroups.add(name=name)
    sun.lightgroup = scene.world.lightgroup = "day"
    lamp.lightgroup = panel.lightgroup = "night"
    return scene, sun, lamp, panel


# ---- a brick wall with a normal map (directional lightmaps) -----------------------------------------------

BRICK_CELL = (12, 6)  # pixels per brick cell of brick_normals (mortar included)
BRICK_WALL_FRAME = np.array([(1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, -1.0, 0.0)])  # rows: T, B, N of brick_wall


def brick_normals(res, cell=BRICK_CELL, bevel=0.5, tilt=0.15, seed=7):
    """A tangent-space normal map (res, res, 3), row 0 = bottom: bricks of cell[0] x cell[1] texels
    (their first column and row: mortar, normal (0, 0, 1)), alternate rows shifted by half a brick;
    each brick's edge texels bevelled outwards (slope `bevel`), its inner texels tilted by a random
    slope up to `tilt` per brick."""
    rng = np.random.default_rng(seed)
    n = np.zeros((res, res, 3))
    n[..., 2] = 1.0
    cw, ch = cell
    tilts = rng.uniform(-tilt, tilt, size=(res // ch + 2, res // cw + 3, 2))
    for i in range(res):
        row = i // ch
        y = i % ch
        for j in range(res):
            shifted = j + (cw // 2 if row % 2 else 0)
            col = shifted // cw
            x = shifted % cw
            if x == 0 or y == 0:
                continue  # mortar
            sx = -bevel if x == 1 else bevel if x == cw - 1 else tilts[row, col, 0]
            sy = -bevel if y == 1 else bevel if y == ch - 1 else tilts[row, col, 1]
            n[i, j] = (sx, sy, 1.0)
    return (n / np.linalg.norm(n, axis=-1, keepdims=True)).astype(np.float32)


def normal_map_image(name, normals):
    """A float Non-Color image of tangent-space normals (0.5 n + 0.5)."""
    h, w, _ = normals.shape
    image = bpy.data.images.new(name, w, h, alpha=False, float_buffer=True)
    image.colorspace_settings.name = 'Non-Color'
    px = np.ones((h, w, 4), np.float32)
    px[..., :3] = 0.5 * normals + 0.5
    image.pixels.foreach_set(px.ravel())
    image.pack()
    return image


def brick_material(name, image, color=(0.6, 0.3, 0.2)):
    """A Principled BSDF (no specular) whose Normal comes from `image` through a Normal Map node
    (tangent space, UV map 'UVMap'), the map read with Closest interpolation."""
    mat = diffuse_material(name, color, principled=True)
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.interpolation = 'Closest'
    uv = nt.nodes.new("ShaderNodeUVMap")
    uv.uv_map = "UVMap"
    nmap = nt.nodes.new("ShaderNodeNormalMap")
    nmap.space = 'TANGENT'
    nmap.uv_map = "UVMap"
    nt.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], nmap.inputs["Color"])
    nt.links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    tex.location, uv.location, nmap.location = (-900, -300), (-1100, -300), (-550, -300)
    return mat


# The brick wall's light: towards the sun 55 degrees from the wall's normal (0, -1, 0), from 45 degrees
# between +x and +z; a uniform sky.
BRICK_SUN = (math.sin(math.radians(55.0)) * math.sqrt(0.5), -math.cos(math.radians(55.0)),
             math.sin(math.radians(55.0)) * math.sqrt(0.5))
BRICK_SKY = (0.35, 0.45, 0.6)


def add_sun(direction, strength, angle=0.0):
    """A sun lamp 'sun' shining from `direction` (towards the sun, any length)."""
    rot = Vector(direction).normalized().to_track_quat('Z', 'Y').to_euler()
    return add_light("sun", 'SUN', (0.0, -3.0, 3.0), tuple(rot), energy=strength, angle=angle)


def brick_wall(res, mat):
    """A 2 x 2 m wall in the xz plane facing -y, UVs (both maps) 0..1 along x and z: its tangent
    frame is BRICK_WALL_FRAME."""
    return quads_object("wall", [((-1, 0, 0), (1, 0, 0), (1, 0, 2), (-1, 0, 2), (0, 0, 1, 1))], mat, res)
