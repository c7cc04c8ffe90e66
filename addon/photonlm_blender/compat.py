"""Differences of Blender's Python API between the versions the add-on serves (3.4, 4.2 LTS to 5.x).

Every place where the add-on's code would depend on the Blender version goes through this module;
the rest of the add-on never looks at bpy.app.version. The differences are found by looking for the
feature (an attribute, a node type, an enum item), not by version numbers, so that a Blender in
between or after behaves as the nearest one with the same API.

    meshes      corner_normals (calc_normals_split before 4.1, Mesh.corner_normals after),
                edge_creases / set_edge_creases / vertex_creases (MeshEdge.crease and
                Mesh.vertex_creases before 4.0, the attributes crease_edge / crease_vert after,
                absent when nothing is creased)
    node groups set_group_outputs (NodeTree.outputs before 4.0, NodeTree.interface after)
    node trees  uses_nodes (Material / World .use_nodes: deprecated in 5.0, always on there)
    shader nodes MIX_COLOR, setup_mix_color, mix_color_sockets (the legacy MixRGB where it exists,
                else Mix in RGBA mode), principled_v2, principled_input (v2 socket names, 4.0+)
    lights      light_emission (colour and power with temperature, exposure and normalize: 5.x has
                them, 4.3 not),
                light_nodes_differ (5.x gives every light a default node tree)
    Cycles      cycles_conventions, set_cycles_conventions (the engine's light conventions: 3.4 or 4+),
                cycles_texel_value (what a Cycles bake's texel holds: its central half before 5.0)
    engines     eevee_engine_id (BLENDER_EEVEE in 3.x and 5.x, BLENDER_EEVEE_NEXT in 4.2-4.4)
    cameras     set_equirectangular (panorama settings on Camera.cycles before 4.0, on Camera after)
    colours     linear_colorspace, is_linear_colorspace ('Linear' before 4.0, 'Linear Rec.709' after)
    glTF        gltf_exporter_types (the glTF exporter's Extension and BinaryData classes: its
                io.exp.gltf2_io_binary_data module became io.exp.binary_data in 4.x)
"""
import math

import bpy


# ---- meshes -----------------------------------------------------------------------------------------------

def corner_normals(mesh):
    """The mesh's normal per loop triangle corner, (T * 9,) float32 in object space: the normals
    Blender shades with (smooth faces interpolated, sharp edges split, custom normals). The mesh
    has its loop triangles. Before 4.1 they are computed by calc_normals_split; from 4.1 they are
    always there as Mesh.corner_normals."""
    import numpy as np
    nt = len(mesh.loop_triangles)
    if hasattr(mesh, "calc_normals_split"):
        mesh.calc_normals_split()
        n = np.empty(nt * 9, np.float32)
        mesh.loop_triangles.foreach_get("split_normals", n)
        return n
    loops = np.empty(nt * 3, np.int32)
    mesh.loop_triangles.foreach_get("loops", loops)
    per_loop = np.empty(len(mesh.loops) * 3, np.float32)
    mesh.corner_normals.foreach_get("vector", per_loop)
    return np.ascontiguousarray(per_loop.reshape(-1, 3)[loops].ravel())


def _attribute_values(mesh, name, domain, count):
    import numpy as np
    attr = mesh.attributes.get(name) if hasattr(mesh, "attributes") else None
    if attr is None or attr.domain != domain or attr.data_type != 'FLOAT' or count == 0:
        return None
    values = np.empty(count, np.float32)
    attr.data.foreach_get("value", values)
    return values


def edge_creases(mesh):
    """Crease per edge (E,) float32, or None when no edge has a crease layer. Before 4.0 an edge
    property (MeshEdge.crease); from 4.0 the float attribute 'crease_edge' on edges, absent until
    something is creased."""
    import numpy as np
    values = _attribute_values(mesh, "crease_edge", 'EDGE', len(mesh.edges))
    if values is not None:
        return values
    if len(mesh.edges) and hasattr(mesh.edges[0], "crease"):
        values = np.empty(len(mesh.edges), np.float32)
        mesh.edges.foreach_get("crease", values)
        return values
    return None


def set_edge_creases(mesh, values):
    """Set every edge's crease from (E,) values (for scripts and tests that build creased meshes):
    MeshEdge.crease before 4.0, the attribute 'crease_edge' (made when missing) after."""
    import numpy as np
    values = np.ascontiguousarray(values, np.float32)
    if len(mesh.edges) and hasattr(mesh.edges[0], "crease"):
        mesh.edges.foreach_set("crease", values)
        return
    attr = mesh.attributes.get("crease_edge") or mesh.attributes.new("crease_edge", 'FLOAT', 'EDGE')
    attr.data.foreach_set("value", values)


def vertex_creases(mesh):
    """Crease per vertex (V,) float32, or None when there is no vertex crease layer. Before 4.0
    the layer Mesh.vertex_creases; from 4.0 the float attribute 'crease_vert' on points."""
    import numpy as np
    values = _attribute_values(mesh, "crease_vert", 'POINT', len(mesh.vertices))
    if values is not None:
        return values
    layers = getattr(mesh, "vertex_creases", None)
    if layers is not None and len(layers) and len(mesh.vertices):
        values = np.empty(len(mesh.vertices), np.float32)
        layers[0].data.foreach_get("value", values)
        return values
    return None


# ---- node groups ------------------------------------------------------------------------------------------

def set_group_outputs(tree, sockets):
    """Make a node group's outputs exactly `sockets`: (name, socket type idname) pairs. Before 4.0
    NodeTree.outputs; from 4.0 the group's interface (items_tree, new_socket)."""
    _set_group_sockets(tree, sockets, 'OUTPUT')


def set_group_inputs(tree, sockets):
    """Make a node group's inputs exactly `sockets`: (name, socket type idname) pairs (as
    set_group_outputs)."""
    _set_group_sockets(tree, sockets, 'INPUT')


def _set_group_sockets(tree, sockets, in_out):
    interface = getattr(tree, "interface", None)
    if interface is not None:
        for item in list(interface.items_tree):
            if getattr(item, "item_type", None) == 'SOCKET' and item.in_out == in_out:
                interface.remove(item)
        for name, socket_type in sockets:
            interface.new_socket(name, in_out=in_out, socket_type=socket_type)
        return
    collection = tree.outputs if in_out == 'OUTPUT' else tree.inputs
    for socket in list(collection):
        collection.remove(socket)
    for name, socket_type in sockets:
        collection.new(socket_type, name)


# ---- materials and worlds -----------------------------------------------------------------------------------

def _use_nodes_deprecated(idblock):
    """use_nodes is gone or deprecated (5.0: getting it always returns True, and warns)."""
    prop = idblock.bl_rna.properties.get("use_nodes")
    return prop is None or bool(getattr(prop, "is_deprecated", False))


def uses_nodes(idblock):
    """Whether a material or world is shaded by its node tree. 5.0 made node trees the only
    way (use_nodes is deprecated there and always on); before, use_nodes says."""
    if idblock is None or idblock.node_tree is None:
        return False
    if _use_nodes_deprecated(idblock):
        return True
    return bool(idblock.use_nodes)


def use_nodes_value(idblock):
    """use_nodes as a value to compare or cache (True where it is deprecated)."""
    return True if _use_nodes_deprecated(idblock) else bool(idblock.use_nodes)


# ---- shader nodes -------------------------------------------------------------------------------------------

# The colour mix of the preview: the legacy MixRGB (Color1, Color2) where Blender still has it,
# else the Mix node in RGBA mode (whose Factor, A and B exist once per data type).
MIX_COLOR = 'ShaderNodeMixRGB' if hasattr(bpy.types, "ShaderNodeMixRGB") else 'ShaderNodeMix'


def setup_mix_color(node, blend_type):
    """Set a MIX_COLOR node to blend colours with `blend_type` (MULTIPLY, ...), factor 1, no clamp
    (setting only what differs: each set updates the node tree). Returns (a, b, result) sockets."""
    if node.bl_idname == 'ShaderNodeMix':
        if node.data_type != 'RGBA':
            node.data_type = 'RGBA'
        if node.clamp_result:
            node.clamp_result = False
        if node.clamp_factor:
            node.clamp_factor = False
    if node.blend_type != blend_type:
        node.blend_type = blend_type
    if getattr(node, "use_clamp", False):
        node.use_clamp = False
    fac, a, b, result = mix_color_sockets(node)
    if fac.default_value != 1.0:
        fac.default_value = 1.0
    return a, b, result


def mix_color_sockets(node):
    """(factor, a, b, result) sockets of a colour mix node (MixRGB, or Mix in RGBA mode)."""
    if node.bl_idname == 'ShaderNodeMix':
        ins = {s.identifier: s for s in node.inputs}
        outs = {s.identifier: s for s in node.outputs}
        return ins["Factor_Float"], ins["A_Color"], ins["B_Color"], outs["Result_Color"]
    return node.inputs['Fac'], node.inputs['Color1'], node.inputs['Color2'], node.outputs['Color']


# Principled BSDF v2 (4.0) renamed these inputs; the keys are the v1 (3.x) names.
_PRINCIPLED_V2 = {
    "Subsurface": "Subsurface Weight",
    "Specular": "Specular IOR Level",
    "Transmission": "Transmission Weight",
    "Clearcoat": "Coat Weight",
    "Clearcoat Roughness": "Coat Roughness",
    "Clearcoat Normal": "Coat Normal",
    "Sheen": "Sheen Weight",
    "Emission": "Emission Color",
}


def principled_v2(node):
    """Whether a Principled BSDF node is v2 (Blender 4.0+: layered, Lambert base)."""
    return "Subsurface Weight" in node.inputs


def principled_input(node, name):
    """The Principled BSDF input that 3.x calls `name`, or None where this Blender has none (v2
    dropped Subsurface Color, for one)."""
    if name in node.inputs:
        return node.inputs[name]
    v2 = _PRINCIPLED_V2.get(name)
    return node.inputs[v2] if v2 is not None and v2 in node.inputs else None


# ---- lights -------------------------------------------------------------------------------------------------

def light_emission(light, world_area=None):
    """(colour, power) of a light as Cycles emits it, in the units of Light.energy with normalize
    on (the only kind 3.4 and 4.3 have). As Cycles' sync: colour x Light.temperature_color where
    use_temperature is on, power x 2^exposure. Where normalize is off Cycles
    does not divide the strength by the light's area (scene/light.cpp, area()), so the same light
    with normalize on takes power x that area: 4 pi r^2 for point and spot lights (4 at radius
    0), the world-space area for area lights (world_area(): sizes along the object's scaled axes,
    disk and ellipse x pi/4; 1 when 0), pi sin^2(angle / 2) for a sun (1 at angle 0)."""
    color = tuple(float(c) for c in light.color)
    power = float(light.energy)
    if getattr(light, "use_temperature", False):
        color = tuple(c * float(t) for c, t in zip(color, light.temperature_color[:3]))
    power *= 2.0 ** float(getattr(light, "exposure", 0.0))
    if not getattr(light, "normalize", True):
        area = 1.0
        if light.type in ('POINT', 'SPOT'):
            area = 4.0 * math.pi * float(light.shadow_soft_size) ** 2 or 4.0
        elif light.type == 'AREA':
            area = (world_area() if world_area is not None else 0.0) or 1.0
        elif light.type == 'SUN' and light.angle > 0.0:
            area = math.pi * math.sin(0.5 * float(light.angle)) ** 2
        power *= area
    return color, power


def light_nodes_differ(light):
    """Whether a light's node tree changes its light: 3.x and 4.x lights have nodes only when
    use_nodes is on; 5.x gives every light a tree. A tree that is only an Emission (colour
    white, strength 1, nothing linked into it) into the Light Output changes nothing."""
    if not _use_nodes_deprecated(light) and not light.use_nodes:
        return False
    tree = light.node_tree
    if tree is None:
        return False
    nodes = [n for n in tree.nodes if n.bl_idname not in ('NodeFrame', 'NodeReroute')]
    outputs = [n for n in nodes if n.bl_idname == 'ShaderNodeOutputLight']
    emissions = [n for n in nodes if n.bl_idname == 'ShaderNodeEmission']
    if len(outputs) != 1 or len(emissions) != 1 or len(nodes) != 2:
        return True
    out, emit = outputs[0], emissions[0]
    surface = out.inputs.get('Surface')
    if surface is None or not surface.is_linked or surface.links[0].from_node != emit \
            or surface.links[0].is_muted:
        return True
    if any(s.is_linked for s in emit.inputs) or out.mute or emit.mute:
        return True
    color, strength = emit.inputs.get('Color'), emit.inputs.get('Strength')
    return (color is None or any(abs(c - 1.0) > 1e-6 for c in color.default_value[:3])
            or strength is None or abs(strength.default_value - 1.0) > 1e-6)


# ---- Cycles ---------------------------------------------------------------------------------------------

def cycles_conventions():
    """The engine's light conventions for this Blender's Cycles (photonlm.Scene.set_conventions):
    "cycles-4" from Blender 4.0 (area light radiance P / (pi A), spot lights without the cosine
    factor), "cycles-3.4" before. This is Cycles' behaviour, not an API that can be looked for, so
    it is read from the version."""
    return "cycles-4" if tuple(bpy.app.version[:2]) >= (4, 0) else "cycles-3.4"


def cycles_texel_value():
    """The engine's texel_value for what this Blender's converged Cycles DIFFUSE bake (box filter
    one texel wide) holds in a texel: "CYCLES" (direct light averaged over the texel's central
    0.5 x 0.5 square) up to 4.x, "AREA" (the whole texel) from 5.0. Measured on a sun shadow edge
    of a rotated blocker across a 32 x 32 floor, relative RMS error against Cycles (its noise
    0.1 %) for central half / whole texel: 3.4.1 0.42 % / 3.77 %, 4.3.2 1.24 % / 3.77 %, 5.2.2
    3.76 % / 0.92 %. 4.4 and 4.5 are not measured; the change is taken to come with 5.0."""
    return "AREA" if tuple(bpy.app.version[:2]) >= (5, 0) else "CYCLES"


def set_cycles_conventions(plm_scene):
    """Give a photonlm.Scene this Blender's Cycles conventions (where the bridge has them)."""
    if hasattr(plm_scene, "set_conventions"):
        plm_scene.set_conventions(cycles_conventions())


# ---- render engines -----------------------------------------------------------------------------------------

def _engine_ids():
    prop = bpy.types.RenderSettings.bl_rna.properties["engine"]
    return {item.identifier for item in prop.enum_items}


def eevee_engine_id():
    """The render engine id of EEVEE: BLENDER_EEVEE_NEXT in 4.2 to 4.4, BLENDER_EEVEE otherwise."""
    return 'BLENDER_EEVEE_NEXT' if 'BLENDER_EEVEE_NEXT' in _engine_ids() else 'BLENDER_EEVEE'


# ---- cameras ------------------------------------------------------------------------------------------------

def set_equirectangular(cam):
    """Make a panoramic camera (type PANO) equirectangular over the whole sphere. The panorama
    settings are Cycles' (Camera.cycles) before 4.0 and the camera's own after."""
    owner = cam if hasattr(cam, "panorama_type") else cam.cycles
    owner.panorama_type = 'EQUIRECTANGULAR'
    owner.latitude_min, owner.latitude_max = -math.pi / 2, math.pi / 2
    owner.longitude_min, owner.longitude_max = -math.pi, math.pi


# ---- colour spaces ------------------------------------------------------------------------------------------

_LINEAR_NAMES = ("Linear Rec.709", "Linear")   # 4.0's name first, then 3.x's


def linear_colorspace(image):
    """The name of scene-linear Rec.709 among the colour spaces of `image`'s colorspace_settings."""
    prop = image.colorspace_settings.bl_rna.properties["name"]
    names = {item.identifier for item in prop.enum_items}
    return next((n for n in _LINEAR_NAMES if n in names), "Linear")


def is_linear_colorspace(name):
    """Whether an image in colour space `name` holds linear values the engine takes as they are."""
    return name in ("Linear", "Linear Rec.709", "Non-Color", "Raw", "Generic Data")


# ---- the glTF exporter (io_scene_gltf2, shipped with Blender) ---------------------------------------------

def gltf_exporter_types(gltf_object):
    """(Extension, BinaryData, gltf2_io) of the glTF exporter that made `gltf_object` (a glTF
    property it passed to a hook): the classes it recognises while writing the file, from the same
    modules it uses. The binary-data module's name changed in 4.x."""
    import importlib
    import sys
    io_module = sys.modules[type(gltf_object).__module__]          # <exporter>.io.com.gltf2_io
    root = io_module.__name__.rsplit(".io.com.", 1)[0]
    extensions = importlib.import_module(root + ".io.com.gltf2_io_extensions")
    for name in (".io.exp.binary_data", ".io.exp.gltf2_io_binary_data"):
        try:
            binary = importlib.import_module(root + name)
            break
        except ImportError:
            continue
    else:
        raise ImportError("the glTF exporter's binary data module was not found under %s" % root)
    return extensions.Extension, binary.BinaryData, io_module
