"""Materials after a bake: the lightmap preview wired into their node trees.

Wiring (for the preview). Baking adds, to every material of a baked object, nodes
tagged node["photonlm"] = role inside a frame labelled "PhotonLM Lightmap":
    UV Map ('lightmap', or 'PhotonLM Atlas' for an atlas page) -> Image Texture (<object>_lightmap,
    or the page <scene>_atlas_<k>_lightmap) -> colour Mix Multiply (compat.MIX_COLOR; factor 1,
    with the diffuse colour: its value, or a link from the socket that feeds the diffuse
    BSDF's colour, times the diffuse weight) -> Emission (Strength 1) -> Add Shader
    (+ Emission of the original emission colour x strength) -> a NEW Material Output.
A material that is not purely diffuse (it has specular lobes) keeps its own shading for
those: closures.py copies its closure nodes without their diffuse part (tagged
"closure_<n>") and an Add Shader ("add_closures") sums them with the lightmap's emission;
the copy carries the material's emission, so the Emission of the original is off there.
With an error image (<object>_error: the texels' relative error, standard error / value, in
R, G and B) the frame also holds the heat map:
    UV Map -> Image Texture (<object>_error) -> Math Divide (by 4 x the target error) ->
    Color Ramp (green up to the target, yellow at 2x, red at 4x and above) -> x a shading
    factor (Layer Weight Facing: 1 facing the view, 0.6 at grazing angles) -> Emission ->
    a second NEW Material Output (tagged "output_error").
The preview mode (OFF / LIGHTMAP / ERROR) only switches which Material Output is active;
the original nodes and links are never changed, and switching the preview off
re-activates the original output (its name is kept in the node tree's ID property
"photonlm_original_output"). A material without the heat map (an orientation-lightmap
lookup) shows its lightmap in ERROR mode. Baking again reuses the tagged nodes.

With light groups (writeback/lightgroups.py) an Image Texture per layer (<object>_lightmap.<group>,
tagged "layer_<k>") feeds the shared node group 'PhotonLM Light Groups' (tagged "light_groups"),
whose mix of the layers by the groups' strengths and tints takes the lightmap image's place in the
Multiply.

With directional lightmaps (writeback/directional.py) an Image Texture per L1 band
(<object>_lightmap_sh1 .. _sh3, tagged "sh_1" .. "sh_3") and the lightmap's colour feed the
shared node group 'PhotonLM Directional' (tagged "directional") with the material's shading
normal (what feeds its BSDF's Normal input, else a Geometry node's Normal, tagged "sh_geometry");
its value of the light at that normal takes the lightmap's place in the Multiply.

A material used by several baked objects can show only one lightmap: it is wired to the
first of those objects (by name) and the bake reports the others. Give each object its
own material (or a single-user copy) to preview all of them. Materials whose outputs are
engine specific (target EEVEE / CYCLES) get a preview output for the scene's render
engine only (reported).
"""
import bpy

from .. import compat
from ..export.materials import ORIGINAL_OUTPUT_KEY, TAG, is_ours, original_output, output_nodes, read_material
from ..export.meshes import LIGHTMAP_UV
from . import closures as preview_closures
from . import directional

ERROR_IMAGE_TAG = "error"  # image[TAG] of the heat-map images the bake loads (<object>_error)
# The heat map's colours at 0, 1, 2 and 4 times the target error (linear RGB).
HEAT_RAMP = ((0.0, (0.02, 0.55, 0.05)), (0.25, (0.02, 0.55, 0.05)), (0.5, (0.9, 0.75, 0.0)),
             (1.0, (0.85, 0.03, 0.02)))
HEAT_GRAZING_DARKEN = 0.4  # the heat map's brightness falls from 1 facing the view to 0.6 at grazing angles


def _node(tree, role, idname, frame=None):
    for n in tree.nodes:
        if n.get(TAG) == role:
            if n.bl_idname == idname:
                return n
            tree.nodes.remove(n)  # a node of the wrong kind carries our tag: replace it
            break
    n = tree.nodes.new(idname)
    n[TAG] = role
    n.name = "PhotonLM " + role
    n.label = "PhotonLM " + role.replace("_", " ")
    if frame is not None:
        n.parent = frame
    return n


def _link(tree, from_socket, to_socket):
    """Link two sockets unless they are linked already: every new link updates the node tree,
    and a bake wires each material again."""
    for link in to_socket.links:
        if link.from_socket == from_socket:
            return link
    return tree.links.new(from_socket, to_socket)


def _set(owner, attr, value):
    """Set owner.attr unless it holds `value` already (floats to 1e-6): each set of a node's
    property updates the node tree (about 14 us), and a bake wires each material again."""
    if not _same(getattr(owner, attr), value):
        setattr(owner, attr, value)


def _same(a, b):
    if isinstance(b, (int, float)) and isinstance(a, (int, float)):
        return abs(a - b) <= 1e-6 * max(1.0, abs(b))
    if isinstance(b, (tuple, list)):
        try:
            return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
        except TypeError:
            return False
    return a == b


def _feed(tree, target, source_socket, default):
    """Make `target` take what `source_socket` takes: the same link, or its default value."""
    source = source_socket.links[0].from_socket if source_socket is not None and source_socket.is_linked else None
    for link in list(target.links):
        if link.from_socket != source:
            tree.links.remove(link)
    if source is not None:
        _link(tree, source, target)
    elif source_socket is not None:
        value = source_socket.default_value
        try:
            _set(target, "default_value", value)
        except (TypeError, ValueError):  # colour -> colour only; keep the fallback otherwise
            _set(target, "default_value", default)
    else:
        _set(target, "default_value", default)


OL_GROUP = "PhotonLM OL Lookup"


def ol_lookup_group():
    """The node group mapping the world-space normal to (u, v) of an orientation lightmap: the
    engine's equal-area octahedral map (Clarberg 2008; ol/octahedral.h): r = sqrt(1 - |z|),
    phi = atan(min / max of |x|, |y|) * 2 / pi (from the x axis), b = phi r, a = r - b; below
    the equator (a, b) -> (1 - b, 1 - a); u = (sign(x) a + 1) / 2, v = (sign(y) b + 1) / 2."""
    g = bpy.data.node_groups.get(OL_GROUP)
    if g is not None and g.get(TAG) == 1:
        return g
    if g is None:
        g = bpy.data.node_groups.new(OL_GROUP, 'ShaderNodeTree')
    g.nodes.clear()
    compat.set_group_outputs(g, [("Vector", 'NodeSocketVector')])
    g[TAG] = 1
    nodes, links = g.nodes, g.links
    out = nodes.new('NodeGroupOutput')
    geo = nodes.new('ShaderNodeNewGeometry')
    sep = nodes.new('ShaderNodeSeparateXYZ')
    links.new(geo.outputs['Normal'], sep.inputs['Vector'])
    x, y, z = sep.outputs['X'], sep.outputs['Y'], sep.outputs['Z']

    def math(op, a, b=None, value_b=0.0):
        n = nodes.new('ShaderNodeMath')
        n.operation = op
        if isinstance(a, float):
            n.inputs[0].default_value = a
        else:
            links.new(a, n.inputs[0])
        if b is not None:
            if isinstance(b, float):
                n.inputs[1].default_value = b
            else:
                links.new(b, n.inputs[1])
        else:
            n.inputs[1].default_value = value_b
        return n.outputs[0]
    ax, ay, az = math('ABSOLUTE', x), math('ABSOLUTE', y), math('ABSOLUTE', z)
    r = math('SQRT', math('MAXIMUM', math('SUBTRACT', 1.0, az), 0.0))
    hi, lo = math('MAXIMUM', ax, ay), math('MINIMUM', ax, ay)
    q = math('DIVIDE', lo, math('MAXIMUM', hi, 1e-12))
    phi = math('MULTIPLY', math('ARCTANGENT', q), 2.0 / 3.141592653589793)
    swap = math('LESS_THAN', ax, ay)  # 1 when |y| > |x|: phi measured from the y axis -> 1 - phi
    phi = math('ADD', phi, math('MULTIPLY', swap, math('SUBTRACT', 1.0, math('MULTIPLY', phi, 2.0))))
    b = math('MULTIPLY', phi, r)
    a = math('SUBTRACT', r, b)
    below = math('LESS_THAN', z, 0.0)
    a2 = math('ADD', a, math('MULTIPLY', below, math('SUBTRACT', math('SUBTRACT', 1.0, b), a)))
    b2 = math('ADD', b, math('MULTIPLY', below, math('SUBTRACT', math('SUBTRACT', 1.0, a), b)))
    # copysign: sign(0) would be 0; use 2 * (x >= 0) - 1.
    sx = math('SUBTRACT', math('MULTIPLY', math('GREATER_THAN', x, -1e-30), 2.0), 1.0)
    sy = math('SUBTRACT', math('MULTIPLY', math('GREATER_THAN', y, -1e-30), 2.0), 1.0)
    u = math('MULTIPLY_ADD', math('MULTIPLY', a2, sx), 0.5)
    v = math('MULTIPLY_ADD', math('MULTIPLY', b2, sy), 0.5)
    for n in nodes:
        if n.bl_idname == 'ShaderNodeMath' and n.operation == 'MULTIPLY_ADD':
            n.inputs[1].default_value = 0.5
            n.inputs[2].default_value = 0.5
    comb = nodes.new('ShaderNodeCombineXYZ')
    links.new(u, comb.inputs['X'])
    links.new(v, comb.inputs['Y'])
    links.new(comb.outputs['Vector'], out.inputs['Vector'])
    return g


def wire_material(mat, image, render_engine, orientation=False, error_image=None, target_error=0.02,
                  uv_map=LIGHTMAP_UV, layers=None, mix=None, sh=None):
    """Add (or update) the preview nodes of `mat` for lightmap `image` read through UV map `uv_map`
    (an atlas page: 'PhotonLM Atlas'; orientation=True: an orientation lightmap looked up by the
    world normal) and, with error_image, the heat map of its relative errors against target_error.
    With light groups, layers ([(group, layer image)]) and mix (the node group 'PhotonLM Light
    Groups') give the lightmap colour instead of `image`: the layers mixed by their groups'
    strengths and tints. With directional lightmaps, sh ([L1 band image] x 3, bands 1, 2, 3) makes
    the lightmap colour the light at the material's shading normal (node group 'PhotonLM
    Directional').
    Returns report strings.
    The active output is not changed here (see set_preview)."""
    notes = []
    if mat is None:
        return notes
    if not compat.uses_nodes(mat):
        return ["material '%s' does not use nodes: no lightmap preview" % mat.name]
    tree = mat.node_tree
    info = read_material(mat)
    orig = original_output(tree)
    _remember_active(tree)

    frame = _node(tree, "frame", 'NodeFrame')
    _set(frame, "label", "PhotonLM Lightmap")
    x0 = (orig.location.x if orig else 0.0) + 300.0
    y0 = (orig.location.y if orig else 0.0) - 400.0
    if orientation:
        uv = _node(tree, "uv", 'ShaderNodeGroup', frame)
        uv.node_tree = ol_lookup_group()
    else:
        uv = _node(tree, "uv", 'ShaderNodeUVMap', frame)
    tex = _node(tree, "image", 'ShaderNodeTexImage', frame)
    mul = _node(tree, "multiply", compat.MIX_COLOR, frame)
    emit = _node(tree, "emission", 'ShaderNodeEmission', frame)
    emit0 = _node(tree, "emission_original", 'ShaderNodeEmission', frame)
    add = _node(tree, "add", 'ShaderNodeAddShader', frame)
    out = _node(tree, "output", 'ShaderNodeOutputMaterial', frame)
    for i, n in enumerate((uv, tex, mul, emit, add, out)):
        _set(n, "location", (x0 + 260.0 * i, y0))
    _set(emit0, "location", (x0 + 260.0 * 3, y0 - 180.0))

    if not orientation:
        _set(uv, "uv_map", uv_map)
    _set(tex, "image", image)
    _set(tex, "interpolation", 'Linear')
    _set(tex, "extension", 'EXTEND')
    mul_a, mul_b, mul_out = compat.setup_mix_color(mul, 'MULTIPLY')
    links = tree.links
    _link(tree, uv.outputs['Vector' if orientation else 'UV'], tex.inputs['Vector'])
    if info.color_socket is not None and info.color_socket.is_linked:
        _feed(tree, mul_a, info.color_socket, (0.8, 0.8, 0.8, 1.0))
        _set(emit.inputs['Strength'], "default_value", info.preview_factor)  # the diffuse weight of that colour
    else:
        _set(emit.inputs['Strength'], "default_value", 1.0)
        _feed(tree, mul_a, None, tuple(info.albedo) + (1.0,))
    light = _light_groups(tree, frame, uv, tex, layers, mix, x0, y0)
    _link(tree, _directional(tree, frame, uv, light, sh, info.surface, x0, y0), mul_b)
    _link(tree, mul_out, emit.inputs['Color'])

    # The specular part keeps the material's own shading (a copy of its closures without the
    # diffuse part, which carries the emission too).
    for n in [n for n in tree.nodes if str(n.get(TAG, "")).startswith(preview_closures.ROLE_PREFIX)]:
        tree.nodes.remove(n)
    closures = None
    if not info.purely_diffuse() and info.surface is not None:
        closures, more = preview_closures.copy_closures(
            tree, info.surface, lambda role, idname: _node(tree, role, idname, frame), x0, y0 - 900.0)
        notes += more
    # The original emission: the same links or values as the shader's emission inputs.
    if closures is not None:
        _feed(tree, emit0.inputs['Color'], None, (0.0, 0.0, 0.0, 1.0))
        _feed(tree, emit0.inputs['Strength'], None, 0.0)
    elif info.emission_color_socket is not None:
        _feed(tree, emit0.inputs['Color'], info.emission_color_socket, (0.0, 0.0, 0.0, 1.0))
        _feed(tree, emit0.inputs['Strength'], info.emission_strength_socket, 0.0)
    else:  # weighted emission (a Mix Shader): the bake's values
        ref = info.emission_texture
        if ref is not None and ref.node.id_data == tree:
            _feed(tree, emit0.inputs['Color'], None, (1.0, 1.0, 1.0, 1.0))
            _link(tree, ref.node.outputs['Color'], emit0.inputs['Color'])
            _feed(tree, emit0.inputs['Strength'], None, float(info.emission[0]))
        else:
            _feed(tree, emit0.inputs['Color'], None, tuple(info.emission) + (1.0,))
            _feed(tree, emit0.inputs['Strength'], None, 1.0 if ref is None else 0.0)
    _link(tree, emit.outputs['Emission'], add.inputs[0])
    _link(tree, emit0.outputs['Emission'], add.inputs[1])
    if closures is not None:
        add2 = _node(tree, "add_closures", 'ShaderNodeAddShader', frame)
        _set(add2, "location", (x0 + 260.0 * 4.5, y0 - 200.0))
        _link(tree, add.outputs['Shader'], add2.inputs[0])
        _link(tree, closures, add2.inputs[1])
        _link(tree, add2.outputs['Shader'], out.inputs['Surface'])
    else:
        for n in [n for n in tree.nodes if n.get(TAG) == "add_closures"]:
            tree.nodes.remove(n)
        _link(tree, add.outputs['Shader'], out.inputs['Surface'])
    for link in list(out.inputs['Volume'].links) + list(out.inputs['Displacement'].links):
        links.remove(link)

    heat_out = None
    if error_image is not None and not orientation:
        heat_out = _wire_heat_map(tree, frame, uv, error_image, target_error, x0, y0 - 360.0)
    else:
        for n in [n for n in tree.nodes if str(n.get(TAG, "")).startswith("error_") or n.get(TAG) == "output_error"]:
            tree.nodes.remove(n)

    targets = {n.target for n in output_nodes(tree)}
    if targets - {'ALL'}:
        engine = 'CYCLES' if render_engine == 'CYCLES' else 'EEVEE'
        target = engine
        notes.append("material '%s' has engine-specific outputs: the lightmap preview shows in %s only"
                     % (mat.name, engine.title()))
    else:
        target = 'ALL'
    for n in (out, heat_out):
        if n is not None:
            _set(n, "target", target)
    return notes


def _light_groups(tree, frame, uv, tex, layers, mix, x0, y0):
    """The socket giving the lightmap colour: the lightmap image's, or with light groups the mix
    node group's over one image node per layer (tagged "layer_<k>", "light_groups")."""
    layers = list(layers or []) if mix is not None else []
    for n in [n for n in tree.nodes if str(n.get(TAG, "")).startswith("layer_")
              and not int(str(n.get(TAG))[len("layer_"):] or 0) < len(layers)]:
        tree.nodes.remove(n)
    if not layers:
        for n in [n for n in tree.nodes if n.get(TAG) == "light_groups"]:
            tree.nodes.remove(n)
        return tex.outputs['Color']
    group = _node(tree, "light_groups", 'ShaderNodeGroup', frame)
    _set(group, "node_tree", mix)
    _set(group, "location", (x0 + 260.0 * 1.5, y0 + 300.0))
    sources = {}
    for k, (layer, image) in enumerate(layers):
        layer_tex = sources[layer] = _node(tree, "layer_%d" % k, 'ShaderNodeTexImage', frame)
        _set(layer_tex, "location", (x0 + 260.0, y0 + 300.0 + 280.0 * (k + 1)))
        _set(layer_tex, "image", image)
        _set(layer_tex, "interpolation", 'Linear')
        _set(layer_tex, "extension", 'EXTEND')
        _link(tree, uv.outputs['UV'], layer_tex.inputs['Vector'])
        _link(tree, layer_tex.outputs['Color'], group.inputs[layer])
    for socket in group.inputs:  # links of an earlier bake's layers go; a layer without an image: no light
        for link in list(socket.links):
            if sources.get(socket.name) != link.from_node:
                tree.links.remove(link)
        if not socket.is_linked and hasattr(socket, "default_value"):
            _set(socket, "default_value", (0.0, 0.0, 0.0, 1.0))
    return group.outputs['Color']


def _directional(tree, frame, uv, light, sh, surface, x0, y0):
    """The socket giving the lightmap colour at the shading normal: `light` without sh, else the
    node group 'PhotonLM Directional' over `light`, one image node per L1 band (tagged "sh_<band>")
    and the normal feeding the diffuse BSDF's Normal input (a Geometry node's, tagged
    "sh_geometry", where that input is not linked)."""
    roles = ["directional", "sh_geometry"] + ["sh_%d" % band for band in directional.BANDS]
    if not sh:
        for n in [n for n in tree.nodes if n.get(TAG) in roles]:
            tree.nodes.remove(n)
        return light
    group = _node(tree, "directional", 'ShaderNodeGroup', frame)
    _set(group, "node_tree", directional.group())
    _set(group, "location", (x0 + 260.0 * 1.5, y0 - 220.0))
    for k, (band, image) in enumerate(zip(directional.BANDS, sh)):
        band_tex = _node(tree, "sh_%d" % band, 'ShaderNodeTexImage', frame)
        _set(band_tex, "location", (x0 + 260.0 * 0.5, y0 - 300.0 - 240.0 * k))
        _set(band_tex, "image", image)
        _set(band_tex, "interpolation", 'Linear')
        _set(band_tex, "extension", 'EXTEND')
        _link(tree, uv.outputs['UV'], band_tex.inputs['Vector'])
        _link(tree, band_tex.outputs['Color'], group.inputs[directional.BAND_INPUTS[k]])
    normal = directional.shading_normal(surface)
    if normal is None:
        geometry = _node(tree, "sh_geometry", 'ShaderNodeNewGeometry', frame)
        _set(geometry, "location", (x0 + 260.0 * 0.5, y0 - 300.0 - 240.0 * 3))
        normal = geometry.outputs['Normal']
    else:
        for n in [n for n in tree.nodes if n.get(TAG) == "sh_geometry"]:
            tree.nodes.remove(n)
    _link(tree, normal, group.inputs['Normal'])
    _link(tree, light, group.inputs['Lightmap'])
    return group.outputs['Color']


def _wire_heat_map(tree, frame, uv, error_image, target_error, x0, y0):
    """UV Map -> error image -> / (4 x target) -> colour ramp -> Emission -> the heat map's output."""
    tex = _node(tree, "error_image", 'ShaderNodeTexImage', frame)
    scale = _node(tree, "error_scale", 'ShaderNodeMath', frame)
    ramp = _node(tree, "error_ramp", 'ShaderNodeValToRGB', frame)
    emit = _node(tree, "error_emission", 'ShaderNodeEmission', frame)
    out = _node(tree, "output_error", 'ShaderNodeOutputMaterial', frame)
    for i, n in enumerate((tex, scale, ramp, emit, out)):
        _set(n, "location", (x0 + 260.0 * (i + 1), y0))
    _set(tex, "image", error_image)
    _set(tex, "interpolation", 'Linear')
    _set(tex, "extension", 'EXTEND')
    _set(scale, "operation", 'DIVIDE')
    _set(scale, "use_clamp", False)
    _set(scale.inputs[1], "default_value", 4.0 * max(float(target_error), 1e-6))
    _set(scale, "label", "PhotonLM error / (4 x %.3g %%)" % (100.0 * target_error))
    _set(ramp.color_ramp, "interpolation", 'LINEAR')
    _set(ramp.color_ramp, "color_mode", 'RGB')
    elements = ramp.color_ramp.elements
    if not _ramp_is(elements, HEAT_RAMP):
        while len(elements) > 1:
            elements.remove(elements[-1])
        elements[0].position = HEAT_RAMP[0][0]
        elements[0].color = tuple(HEAT_RAMP[0][1]) + (1.0,)
        for position, colour in HEAT_RAMP[1:]:
            elements.new(position).color = tuple(colour) + (1.0,)
    links = tree.links
    _link(tree, uv.outputs['UV'], tex.inputs['Vector'])
    _link(tree, tex.outputs['Color'], scale.inputs[0])
    _link(tree, scale.outputs['Value'], ramp.inputs['Fac'])
    # Faces seen at a grazing angle a little darker, so that the shapes read under flat colours.
    facing = _node(tree, "error_facing", 'ShaderNodeLayerWeight', frame)
    shade = _node(tree, "error_shade", 'ShaderNodeMath', frame)
    mix = _node(tree, "error_shading", compat.MIX_COLOR, frame)
    _set(facing, "location", (x0 + 260.0 * 2, y0 - 220.0))
    _set(shade, "location", (x0 + 260.0 * 3, y0 - 220.0))
    _set(mix, "location", (x0 + 260.0 * 3.5, y0 - 110.0))
    _set(facing.inputs['Blend'], "default_value", 0.5)
    _set(shade, "operation", 'MULTIPLY_ADD')
    _set(shade, "use_clamp", True)
    _set(shade.inputs[1], "default_value", -HEAT_GRAZING_DARKEN)
    _set(shade.inputs[2], "default_value", 1.0)
    mix_a, mix_b, mix_out = compat.setup_mix_color(mix, 'MULTIPLY')
    _link(tree, facing.outputs['Facing'], shade.inputs[0])
    _link(tree, ramp.outputs['Color'], mix_a)
    _link(tree, shade.outputs['Value'], mix_b)
    _link(tree, mix_out, emit.inputs['Color'])
    _set(emit.inputs['Strength'], "default_value", 1.0)
    _link(tree, emit.outputs['Emission'], out.inputs['Surface'])
    for link in list(out.inputs['Volume'].links) + list(out.inputs['Displacement'].links):
        links.remove(link)
    return out


def _ramp_is(elements, stops):
    """Whether a colour ramp's elements are `stops` ((position, rgb), ...), to float precision."""
    return len(elements) == len(stops) and all(
        abs(e.position - p) < 1e-6 and all(abs(a - b) < 1e-6 for a, b in zip(e.color, tuple(c) + (1.0,)))
        for e, (p, c) in zip(elements, stops))


def _remember_active(tree):
    """Remember which original Material Output carries the active flag (unless ours has it)."""
    if any(is_ours(n) and n.is_active_output for n in output_nodes(tree, True)):
        return
    flagged = [n for n in output_nodes(tree) if n.is_active_output]
    if flagged:
        tree[ORIGINAL_OUTPUT_KEY] = flagged[0].name
    elif ORIGINAL_OUTPUT_KEY not in tree:
        orig = original_output(tree)
        if orig is not None:
            tree[ORIGINAL_OUTPUT_KEY] = orig.name


def is_wired(mat):
    return (mat is not None and compat.uses_nodes(mat)
            and any(n.get(TAG) == "output" for n in mat.node_tree.nodes))


PREVIEW_MODES = ('OFF', 'LIGHTMAP', 'ERROR')


def preview_mode(value):
    """A preview mode from a mode name or a bool (True = LIGHTMAP, False = OFF)."""
    if value in PREVIEW_MODES:
        return value
    return 'LIGHTMAP' if value else 'OFF'


def set_preview(mat, mode):
    """Activate the output of preview `mode` of a wired material: 'LIGHTMAP' (or True) its lightmap
    output, 'ERROR' its heat-map output (the lightmap output where it has none), 'OFF' (or False)
    the original output."""
    if not is_wired(mat):
        return
    mode = preview_mode(mode)
    tree = mat.node_tree
    ours = next(n for n in tree.nodes if n.get(TAG) == "output")
    if mode == 'ERROR':
        ours = next((n for n in tree.nodes if n.get(TAG) == "output_error"), ours)
    if mode != 'OFF':
        if ours.is_active_output:
            return
        _remember_active(tree)
        for n in output_nodes(tree, True):
            if n != ours and n.is_active_output:
                n.is_active_output = False
        ours.is_active_output = True
    else:
        name = tree.get(ORIGINAL_OUTPUT_KEY)
        orig = tree.nodes.get(name) if name else None
        if orig is None or is_ours(orig):
            candidates = output_nodes(tree)
            orig = candidates[0] if candidates else None
        for n in output_nodes(tree, True):
            if is_ours(n):
                n.is_active_output = False
        if orig is not None:
            orig.is_active_output = True


def set_preview_all(mode):
    for mat in bpy.data.materials:
        set_preview(mat, mode)


def remove_wiring(mat):
    """Remove the preview nodes (lightmap and heat map) from a material and re-activate its
    original output."""
    if mat is None or mat.node_tree is None:
        return False
    set_preview(mat, 'OFF')
    tree = mat.node_tree
    ours = [n for n in tree.nodes if is_ours(n)]
    frames = [n for n in ours if n.bl_idname == 'NodeFrame']
    for n in ours:
        if n.bl_idname != 'NodeFrame':
            tree.nodes.remove(n)
    for n in frames:  # after their children
        tree.nodes.remove(n)
    if ORIGINAL_OUTPUT_KEY in tree:
        del tree[ORIGINAL_OUTPUT_KEY]
    return bool(ours)


def remove_error_images():
    """Remove the heat-map images (<object>_error) no material uses any more; their files stay.
    Returns how many were removed."""
    unused = [im for im in bpy.data.images if im.get(TAG) == ERROR_IMAGE_TAG and im.users == 0]
    for im in unused:
        bpy.data.images.remove(im)
    return len(unused)
