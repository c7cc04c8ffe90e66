"""Directional lightmaps (scene.photonlm.directional): the direction of each texel's light, so that
normal maps and bump respond to the baked light.

The engine keeps, per texel and channel, the light's first-order spherical harmonics (SH L1) in
Godot 4's layout: band 0 is L0, bands 1, 2, 3 are L1 m = -1, 0, 1 along the world's y, z and x
axes (photonlm.h, "Directional lightmaps"). A surface of unit world normal n at the texel receives

    value(n) = 0.282095 L0 + 0.32573 (L1_-1 n.y + L1_0 n.z + L1_1 n.x)

in the lightmap's units, and L0 is the lightmap V / (2 x 0.282095), so that

    value(n) = V / 2 + D . n,   D = 0.32573 (L1_1, L1_-1, L1_0) per channel.

The write-back keeps L0 as the lightmap itself and writes the three L1 bands beside it,
<object>_lightmap_sh1.exr .. _sh3.exr (atlas pages: <page>_lightmap_sh1.exr ..; the names
`photonlm bake` gives them), loaded as float images <object>_lightmap_sh1 .. _sh3. The preview
evaluates value(n) with the material's shading normal (the normal that feeds its BSDF's Normal
input: a Normal Map or Bump node, else the geometry's) in one shared node group, GROUP
("PhotonLM Directional"), clamped at 0. A bake without directions removes the bands an earlier
directional bake left beside its lightmaps (remove_stale_bands).
"""
import os

import bpy

from .. import compat
from ..export.materials import TAG

GROUP = "PhotonLM Directional"
GROUP_VERSION = 1                 # on the node group (VERSION_KEY): remade when it changes
VERSION_KEY = "photonlm_directional"
BANDS = (1, 2, 3)                 # the L1 bands the write-back keeps (L0 is the lightmap)
BAND_INPUTS = ("L1 -1 (y)", "L1 0 (z)", "L1 1 (x)")  # the group's inputs of bands 1, 2, 3
SH_L0 = 0.282095                  # Y_0^0
SH_L1 = 0.32573                   # Godot 4's L1 factor: 2/3 x sqrt(3 / (4 pi))
# The BSDFs whose Normal input is the diffuse shading normal (the first found from the output).
DIFFUSE_BSDFS = ('ShaderNodeBsdfPrincipled', 'ShaderNodeBsdfDiffuse')


def band_file(path, band):
    """The file of SH band `band` beside the lightmap file `path` (..._lightmap.exr):
    ..._lightmap_sh<band>.exr, as `photonlm bake` names it."""
    stem = path[:-len(".exr")] if path.endswith(".exr") else path
    return "%s_sh%d.exr" % (stem, band)


def band_image_name(base, band):
    """The image of SH band `band` of the lightmap image `base` (<object>_lightmap, a page's)."""
    return "%s_sh%d" % (base, band)


def remove_stale_bands(lightmap_files, lightmap_images):
    """After a bake without directions: remove the L1 band files beside `lightmap_files` and the
    band images of `lightmap_images` (names) that no material uses any more, left by an earlier
    directional bake (they would not match the new lightmaps)."""
    for path in lightmap_files:
        for band in BANDS:
            f = band_file(path, band)
            if os.path.isfile(f):
                os.remove(f)
    for base in lightmap_images:
        for band in BANDS:
            image = bpy.data.images.get(band_image_name(base, band))
            if image is not None and image.users == 0:
                bpy.data.images.remove(image)


def shading_normal(surface):
    """The socket whose normal the material's diffuse part is shaded with: what feeds the Normal
    input of the first Principled or Diffuse BSDF found from `surface` (the Material Output's
    Surface input) through shader mixes and adds; None where that input is not linked (the geometry
    normal) or no such BSDF is found."""
    if surface is None or not surface.is_linked:
        return None
    seen, queue = set(), [surface.links[0].from_node]
    while queue:
        node = queue.pop(0)
        if node.name in seen:
            continue
        seen.add(node.name)
        if node.bl_idname in DIFFUSE_BSDFS:
            socket = node.inputs.get('Normal')
            return socket.links[0].from_socket if socket is not None and socket.is_linked else None
        for socket in node.inputs:
            if socket.type == 'SHADER' or node.bl_idname == 'NodeReroute':
                queue.extend(link.from_node for link in socket.links)
    return None


def group():
    """The node group GROUP: inputs Lightmap (V), the three L1 bands and Normal (world space, unit),
    output Color = max(V / 2 + D . n, 0) (see the module text); made once per file."""
    g = bpy.data.node_groups.get(GROUP)
    if g is not None and g.get(VERSION_KEY) == GROUP_VERSION:
        return g
    if g is None:
        g = bpy.data.node_groups.new(GROUP, 'ShaderNodeTree')
    g.nodes.clear()
    compat.set_group_inputs(g, [("Lightmap", 'NodeSocketColor')]
                            + [(name, 'NodeSocketColor') for name in BAND_INPUTS]
                            + [("Normal", 'NodeSocketVector')])
    compat.set_group_outputs(g, [("Color", 'NodeSocketColor')])
    g[TAG] = 1
    g[VERSION_KEY] = GROUP_VERSION
    nodes, links = g.nodes, g.links
    gin = nodes.new('NodeGroupInput')
    gin.location = (-900.0, 0.0)
    gout = nodes.new('NodeGroupOutput')
    gout.location = (700.0, 0.0)
    normal = nodes.new('ShaderNodeVectorMath')  # a unit normal whatever feeds it
    normal.operation = 'NORMALIZE'
    normal.location = (-700.0, -300.0)
    links.new(gin.outputs["Normal"], normal.inputs[0])
    xyz = nodes.new('ShaderNodeSeparateXYZ')
    xyz.location = (-500.0, -300.0)
    links.new(normal.outputs['Vector'], xyz.inputs[0])
    total = None
    # band input -> the normal's component it multiplies: L1_-1 by y, L1_0 by z, L1_1 by x
    for i, (name, axis) in enumerate(zip(BAND_INPUTS, ('Y', 'Z', 'X'))):
        scaled = _vector_math(nodes, 'SCALE', (-300.0, -160.0 * i))
        links.new(gin.outputs[name], scaled.inputs[0])
        links.new(xyz.outputs[axis], scaled.inputs['Scale'])
        if total is None:
            total = scaled.outputs['Vector']
        else:
            add = _vector_math(nodes, 'ADD', (-100.0, -160.0 * i))
            links.new(total, add.inputs[0])
            links.new(scaled.outputs['Vector'], add.inputs[1])
            total = add.outputs['Vector']
    d = _vector_math(nodes, 'SCALE', (100.0, -160.0))
    d.inputs['Scale'].default_value = SH_L1
    links.new(total, d.inputs[0])
    half = _vector_math(nodes, 'SCALE', (100.0, 120.0))
    half.inputs['Scale'].default_value = 0.5  # 0.282095 L0 = V / 2
    links.new(gin.outputs["Lightmap"], half.inputs[0])
    add = _vector_math(nodes, 'ADD', (300.0, 0.0))
    links.new(half.outputs['Vector'], add.inputs[0])
    links.new(d.outputs['Vector'], add.inputs[1])
    clamp = _vector_math(nodes, 'MAXIMUM', (500.0, 0.0))
    clamp.inputs[1].default_value = (0.0, 0.0, 0.0)
    links.new(add.outputs['Vector'], clamp.inputs[0])
    links.new(clamp.outputs['Vector'], gout.inputs["Color"])
    return g


def _vector_math(nodes, operation, location):
    n = nodes.new('ShaderNodeVectorMath')
    n.operation = operation
    n.location = location
    return n
