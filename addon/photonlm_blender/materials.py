"""Materials: what the engine needs from a Blender material, and the lightmap preview wiring.

Reading (for the bake). The material's active Material Output (Cycles' choice: an output
whose target is CYCLES wins over ALL, the active one wins among equals) is followed
through its Surface link; flatten.py turns the closures it reaches (Principled, Diffuse,
Glossy, Glass, Refraction, Transparent BSDFs and Emission, through Mix and Add Shaders and
node groups) into one diffuse albedo, an emission and a list of specular lobes, with Cycles
3.4's weights. An Image Texture node linked into the colour of the diffuse part (its Vector
unlinked or from a UV Map node) becomes an engine albedo texture (albedo = image x the
diffuse weight) on the UV map it reads (export_textures, texture_uv); one into an emission
colour becomes an emission texture (radiance = image x strength x weight). A procedurally
linked diffuse colour is baked as grey 0.8, other linked emission as none (reported). A
material without nodes uses its viewport colour (material.diffuse_color). What the engine
has no exact counterpart for is reported once per material (flatten.py lists it).

Wiring (for the preview). Baking adds, to every material of a baked object, nodes
tagged node["photonlm"] = role inside a frame labelled "PhotonLM Lightmap":
    UV Map ('lightmap', or 'PhotonLM Atlas' for an atlas page) -> Image Texture (<object>_lightmap,
    or the page <scene>_atlas_<k>_lightmap) -> colour Mix Multiply (compat.MIX_COLOR; factor 1,
    with the diffuse colour: its value, or a link from the socket that feeds the diffuse
    BSDF's colour, times the diffuse weight) -> Emission (Strength 1) -> Add Shader
    (+ Emission of the original emission colour x strength) -> a NEW Material Output.
A material that is not purely diffuse (it has specular lobes) keeps its own shading for
those: preview_closures.py copies its closure nodes without their diffuse part (tagged
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

A material used by several baked objects can show only one lightmap: it is wired to the
first of those objects (by name) and the bake reports the others. Give each object its
own material (or a single-user copy) to preview all of them. Materials whose outputs are
engine specific (target EEVEE / CYCLES) get a preview output for the scene's render
engine only (reported).
"""
import bpy

from . import compat, flatten, preview_closures

TAG = "photonlm"
ORIGINAL_OUTPUT_KEY = "photonlm_original_output"
ERROR_IMAGE_TAG = "error"  # image[TAG] of the heat-map images the bake loads (<object>_error)
# The heat map's colours at 0, 1, 2 and 4 times the target error (linear RGB).
HEAT_RAMP = ((0.0, (0.02, 0.55, 0.05)), (0.25, (0.02, 0.55, 0.05)), (0.5, (0.9, 0.75, 0.0)),
             (1.0, (0.85, 0.03, 0.02)))
HEAT_GRAZING_DARKEN = 0.4  # the heat map's brightness falls from 1 facing the view to 0.6 at grazing angles
FALLBACK_ALBEDO = (0.8, 0.8, 0.8)
LIGHTMAP_UV = "lightmap"


class MaterialInfo:
    """What the bake uses from one material, and where its colours come from (for the preview)."""

    def __init__(self, name):
        self.name = name
        self.albedo = FALLBACK_ALBEDO
        self.emission = (0.0, 0.0, 0.0)
        self.lobes = []            # flatten.Lobe: the specular part, in the order the engine sums them
        self.burley = None         # Burley diffuse roughness (Blender 3.x's Principled BSDF), None: Lambert
        self.notes = []            # reports about approximations
        self.color_socket = None   # the input giving the diffuse colour by a link (NodeSocket) or None
        self.preview_factor = 1.0  # the diffuse weight multiplying that colour
        self.emission_color_socket = None   # the emission's inputs when it is one unweighted Emission
        self.emission_strength_socket = None
        self.albedo_texture = None     # TextureRef: Image Texture node into the diffuse colour
        self.emission_texture = None   # TextureRef: Image Texture node into the emission colour
        self.surface = None        # the original Material Output's Surface input (for the preview)

    def purely_diffuse(self):
        return not self.lobes


class TextureRef:
    """An Image Texture node the engine looks up itself: its image and the UV map it reads
    (None = the mesh's active render UV map)."""

    def __init__(self, node, uv_map):
        self.node = node
        self.image = node.image
        self.uv_map = uv_map


def _image_texture(mat, socket, what, info, path=()):
    """TextureRef when socket (inside the node groups `path`) is fed by an Image Texture node the
    engine can look up (an image, its Vector unlinked or from a UV Map node, Repeat extension);
    else None with a note."""
    src = flatten.source(socket, path)
    node = src[0].node if src is not None else None
    if node is None or node.bl_idname != 'ShaderNodeTexImage':
        kind = node.bl_label if node is not None else "a link"
        info.notes.append("material '%s': %s comes from %s (not an Image Texture): baked as grey 0.8"
                          % (mat.name, what, kind) if what == "Base Color" else
                          "material '%s': %s comes from %s (not an Image Texture): baked without emission"
                          % (mat.name, what, kind))
        return None
    if node.image is None:
        info.notes.append("material '%s': Image Texture '%s' has no image: %s ignored" % (mat.name, node.name, what))
        return None
    uv_map = None
    vec = node.inputs['Vector']
    if vec.is_linked:
        vsrc = flatten.source(vec, src[1])
        src = vsrc[0].node if vsrc is not None else None
        if src is None or src.bl_idname != 'ShaderNodeUVMap':
            info.notes.append("material '%s': Image Texture '%s' reads coordinates from '%s' (only a UV Map node "
                              "is supported): the mesh's render UV map is used"
                              % (mat.name, node.name, src.bl_label if src else "?"))
        else:
            uv_map = src.uv_map or None
    if node.extension != 'REPEAT':
        info.notes.append("material '%s': Image Texture '%s' uses extension %s: baked as Repeat"
                          % (mat.name, node.name, node.extension))
    return TextureRef(node, uv_map)


def _is_ours(node):
    return node.get(TAG) is not None


def _output_nodes(tree, include_ours=False):
    return [n for n in tree.nodes if n.bl_idname == 'ShaderNodeOutputMaterial'
            and (include_ours or not _is_ours(n))]


def original_output(tree, target='CYCLES'):
    """The Material Output the material uses without the preview, chosen as Blender chooses
    (exact target before ALL, the active one among equals). While the preview is on, the
    output remembered in ORIGINAL_OUTPUT_KEY counts as the active one."""
    outputs = _output_nodes(tree)
    if not outputs:
        return None
    ours_active = any(n.is_active_output for n in _output_nodes(tree, True) if _is_ours(n))
    remembered = tree.get(ORIGINAL_OUTPUT_KEY)

    def active(n):
        return (n.name == remembered) if (ours_active and remembered) else n.is_active_output

    best = None
    for n in outputs:
        if n.target == 'ALL':
            if best is None or (best.target == 'ALL' and active(n) and not active(best)):
                best = n
        elif n.target == target:
            if best is None or best.target == 'ALL' or (active(n) and not active(best)):
                best = n
    return best


def _follow(socket):
    """The node feeding an input socket, skipping reroutes and muted links; None if unlinked."""
    seen = 0
    while socket is not None and socket.is_linked and seen < 64:
        link = socket.links[0]
        if link.is_muted or not link.is_valid:
            return None
        node = link.from_node
        if node.bl_idname == 'NodeReroute':
            socket = node.inputs[0]
            seen += 1
            continue
        return node
    return None


def read_material(mat, image_means=None):
    """MaterialInfo for a Blender material (None -> the default grey material). image_means
    caches image means between materials of one export."""
    info = MaterialInfo(mat.name if mat else "PhotonLM default")
    if mat is None:
        return info
    if not compat.uses_nodes(mat):
        info.albedo = tuple(float(c) for c in mat.diffuse_color[:3])
        info.notes.append("material '%s' does not use nodes: baked with its viewport colour" % mat.name)
        return _clamp(info)
    out = original_output(mat.node_tree)
    if out is None or flatten.source(out.inputs['Surface']) is None:
        info.notes.append("material '%s' has no shader on its Material Output: baked as grey 0.8" % mat.name)
        return info
    info.surface = out.inputs['Surface']
    image_means = image_means if image_means is not None else {}
    flat = flatten.flatten(info.surface, image_means)
    info.lobes = flat.lobes
    info.burley = flat.burley
    albedo = tuple(flat.albedo)
    if flat.texture_socket is not None:
        socket, path = flat.texture_socket
        ref = _image_texture(mat, socket, "Base Color", info, path)
        if ref is None:
            albedo = tuple(a + flat.texture_factor * c for a, c in zip(albedo, FALLBACK_ALBEDO))
        else:
            info.albedo_texture = ref
            f = flat.texture_factor
            factor = (f, f, f)
            if max(albedo) > 0.0:  # a constant diffuse colour beside the image: folded in by the image's mean
                mean = image_means.get(ref.image.name_full) or flatten.image_mean(ref.image)
                if mean is not None and min(mean[0]) > 0.0:
                    factor = tuple(f + a / m for a, m in zip(albedo, mean[0]))
                flat.approx("a constant diffuse colour beside the image '%s' folded into it by the image's "
                            "mean" % ref.image.name)
            albedo = factor
            if not path:
                info.color_socket, info.preview_factor = socket, f
    elif flat.preview_socket is not None and not flat.preview_socket[1]:
        info.color_socket, info.preview_factor = flat.preview_socket[0], flat.linked_factor
    info.albedo = albedo
    emission = tuple(flat.emission)
    if flat.emission_texture_socket is not None:
        socket, path = flat.emission_texture_socket
        ref = _image_texture(mat, socket, "Emission", info, path)
        if ref is not None:
            info.emission_texture = ref
            if max(emission) > 0.0:
                flat.approx("a constant emission beside the emission image '%s' left out" % ref.image.name)
            emission = (flat.emission_texture_strength,) * 3
    info.emission = emission
    if flat.emission_leaves == 1 and flat.emission_sockets is not None:
        info.emission_color_socket, info.emission_strength_socket = flat.emission_sockets
    for _kind, text in flat.notes:
        info.notes.append("material '%s': %s" % (mat.name, text))
    if flat.approximations:
        info.notes.append("material '%s': approximated for the bake: %s" % (mat.name, "; ".join(flat.approximations)))
    return _clamp(info)


def _clamp(info):
    if any(c > 1.0 for c in info.albedo) or any(c < 0.0 for c in info.albedo):
        info.notes.append("material '%s': albedo %s clamped to [0, 1]"
                          % (info.name, tuple(round(c, 3) for c in info.albedo)))
        info.albedo = tuple(min(max(c, 0.0), 1.0) for c in info.albedo)
    return info


# ---- preview wiring ------------------------------------------------------------------------

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
                  uv_map=LIGHTMAP_UV):
    """Add (or update) the preview nodes of `mat` for lightmap `image` read through UV map `uv_map`
    (an atlas page: 'PhotonLM Atlas'; orientation=True: an orientation lightmap looked up by the
    world normal) and, with error_image, the heat map of its relative errors against target_error.
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
    _link(tree, tex.outputs['Color'], mul_b)
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

    targets = {n.target for n in _output_nodes(tree)}
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
    if any(_is_ours(n) and n.is_active_output for n in _output_nodes(tree, True)):
        return
    flagged = [n for n in _output_nodes(tree) if n.is_active_output]
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
        for n in _output_nodes(tree, True):
            if n != ours and n.is_active_output:
                n.is_active_output = False
        ours.is_active_output = True
    else:
        name = tree.get(ORIGINAL_OUTPUT_KEY)
        orig = tree.nodes.get(name) if name else None
        if orig is None or _is_ours(orig):
            candidates = _output_nodes(tree)
            orig = candidates[0] if candidates else None
        for n in _output_nodes(tree, True):
            if _is_ours(n):
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
    ours = [n for n in tree.nodes if _is_ours(n)]
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


# ---- image textures for the engine ---------------------------------------------------------

# File types the engine decodes itself (native/src/io/image_file.h); Blender decodes the others
# (TIFF, WebP, ...) and the add-on hands over their pixels.
ENGINE_IMAGE_TYPES = (".exr", ".hdr", ".pfm", ".png", ".jpg", ".jpeg", ".bmp", ".tga", ".psd", ".gif")


def engine_reads(path):
    return path.lower().endswith(ENGINE_IMAGE_TYPES)


class TextureFiles:
    """Images handed to the engine: file-backed images by their path where the engine reads the
    file type; packed, generated or edited ones and other file types written to a private
    temporary directory (removed by cleanup())."""

    def __init__(self):
        self.dir = None
        self.paths = {}  # image name -> (path, colorspace)

    def path_of(self, image):
        import os
        key = image.name_full
        if key in self.paths:
            return self.paths[key]
        path = bpy.path.abspath(image.filepath, library=image.library) if image.filepath else ""
        space = "srgb" if image.colorspace_settings.name == 'sRGB' else "linear"
        if not (image.source == 'FILE' and not image.packed_file and not image.is_dirty
                and path and os.path.isfile(path) and engine_reads(path)):
            path, space = self._write_pixels(image)
        self.paths[key] = (path, space)
        return self.paths[key]

    def _write_pixels(self, image):
        """The image's pixels as PPM (byte images, as stored: sRGB stays encoded) or PFM (float
        images, scene linear)."""
        import os
        import tempfile
        import numpy as np
        if self.dir is None:
            self.dir = tempfile.mkdtemp(prefix="photonlm-images-")
        w, h = image.size
        if w == 0 or h == 0:
            raise ValueError("image '%s' has no pixels" % image.name)
        px = np.empty(w * h * image.channels, np.float32)
        image.pixels.foreach_get(px)
        px = px.reshape(h, w, image.channels)
        rgb = px[..., :3] if image.channels >= 3 else np.repeat(px[..., :1], 3, axis=2)
        name = "%d" % len(self.paths)
        if image.is_float:
            path = os.path.join(self.dir, name + ".pfm")
            with open(path, "wb") as f:  # PFM rows run bottom to top, like Blender's pixels
                f.write(b"PF\n%d %d\n-1.0\n" % (w, h))
                f.write(np.ascontiguousarray(rgb, "<f4").tobytes())
            return path, "linear"
        path = os.path.join(self.dir, name + ".ppm")
        with open(path, "wb") as f:  # PPM rows run top to bottom
            f.write(b"P6\n%d %d\n255\n" % (w, h))
            f.write(np.clip(np.rint(rgb[::-1] * 255.0), 0, 255).astype(np.uint8).tobytes())
        return path, "srgb" if image.colorspace_settings.name == 'sRGB' else "linear"

    def cleanup(self):
        import shutil
        if self.dir is not None:
            shutil.rmtree(self.dir, ignore_errors=True)
            self.dir = None
        self.paths = {}


def export_textures(plm, material_id, info, files, reports):
    """Give engine material material_id the textures of info (if the scene supports them).
    A texture the engine cannot read is reported and the material keeps its fallback colour."""
    if not hasattr(plm, "set_material_texture"):
        if info.albedo_texture or info.emission_texture:
            reports.warning("material '%s': textures are not exported here: their mean is not known, "
                            "baked with constant colours" % info.name)
        return
    for slot, ref in (("albedo", info.albedo_texture), ("emission", info.emission_texture)):
        if ref is None:
            continue
        try:
            path, space = files.path_of(ref.image)
            plm.set_material_texture(material_id, slot, path, space)
        except Exception as e:  # noqa: BLE001 -- reported; the bake goes on without the texture
            reports.warning("material '%s': %s texture '%s' not used: %s"
                            % (info.name, slot, ref.image.name, getattr(e, "message", e)))


def export_lobes(plm, material_id, info, reports):
    """Give engine material material_id the specular lobes of info. A FRESNEL or SPECULAR lobe goes
    as its F0 (color / weight) and weight; the others with weight 1 (their colour carries the mix factors).
    A lobe the engine refuses is reported and left out. A Burley diffuse part (info.burley) goes as
    the material's diffuse model."""
    if info.burley is not None and hasattr(plm, "set_material_diffuse"):
        try:
            plm.set_material_diffuse(material_id, "burley", info.burley)
        except Exception as e:  # noqa: BLE001 -- reported; the bake goes on with Lambert's diffuse
            reports.warning("material '%s': Burley diffuse baked as Lambert: %s" % (info.name, getattr(e, "message", e)))
    if not info.lobes:
        return
    if not hasattr(plm, "add_material_lobe"):
        reports.warning("material '%s': the engine takes no specular lobes here: its %s part is left out"
                        % (info.name, ", ".join(sorted({l.kind for l in info.lobes}))))
        return
    for lobe in info.lobes:
        color, weight = lobe.color, 1.0
        if lobe.kind in flatten.LAYER_KINDS:
            weight = min(max(lobe.weight, 0.0), 1.0)
            color = tuple(min(max(c / lobe.weight, 0.0), 1.0) for c in lobe.color) if lobe.weight > 0.0 \
                else (0.0, 0.0, 0.0)
        try:
            plm.add_material_lobe(material_id, lobe.kind, color, roughness=lobe.roughness, ior=lobe.ior,
                                  abbe=lobe.abbe, weight=weight)
        except Exception as e:  # noqa: BLE001 -- reported; the bake goes on without the lobe
            reports.warning("material '%s': %s lobe left out: %s" % (info.name, lobe.kind, getattr(e, "message", e)))


def texture_uv(mesh, infos, object_name, reports):
    """(T, 3, 2) float32 texture UVs of an evaluated mesh (loop triangles) for its textured
    materials, or None when none is textured. One UV map per mesh: the first textured
    material's (a UV Map node's, else the active render UV map); others are reported."""
    import numpy as np
    wanted = []
    for info in infos:
        for ref in (info.albedo_texture, info.emission_texture) if info is not None else ():
            if ref is not None and ref.uv_map not in wanted:
                wanted.append(ref.uv_map)
    if not wanted:
        return None
    name = wanted[0]
    layer = mesh.uv_layers.get(name) if name else next((l for l in mesh.uv_layers if l.active_render), None)
    if len(wanted) > 1:
        reports.warning("object '%s': its textures read different UV maps %s: all use '%s'"
                        % (object_name, wanted, layer.name if layer else name))
    if layer is None:
        reports.warning("object '%s': no UV map '%s' for its textures: their mean colour is used"
                        % (object_name, name or "(render)"))
        return None
    nt = len(mesh.loop_triangles)
    loops = np.empty(nt * 3, np.int32)
    mesh.loop_triangles.foreach_get("loops", loops)
    loop_uv = np.empty(len(mesh.loops) * 2, np.float32)
    layer.data.foreach_get("uv", loop_uv)
    return loop_uv.reshape(-1, 2)[loops].reshape(nt, 3, 2)
