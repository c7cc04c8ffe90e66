"""The light groups' mix: relighting the preview without baking again.

A bake with light groups (export/lightgroups.py) gives each lightmap one layer per group; the
write-back loads them as images <object>_lightmap.<group> (atlas pages: <page>_lightmap.<group>).
Each group has a strength and a tint on the scene, scene.photonlm.light_groups[<group>] (plain
properties: sliders in the panel, keyframes and drivers work on them). One shared node group,
MIX_GROUP ("PhotonLM Light Groups"), takes the layers' colours as inputs, one per layer named
after its group, and gives
    sum over layers of  layer x tint x strength
inside it each group's strength is a Value node and its tint an RGB node whose values are drivers
reading the scene's properties, so that an animation of them reaches every material's preview.
With every strength 1 and every tint white it gives the plain lightmap (the layers add up to it).
"""
import bpy

from .. import compat
from ..export.materials import TAG

MIX_GROUP = "PhotonLM Light Groups"
LAYERS_KEY = "photonlm_layers"   # on the node group: its layers, comma-separated
SCENE_KEY = "photonlm_scene"     # on the node group: the name of the scene its drivers read


def settings_path(layer, prop):
    """The data path, from the scene, of a group's strength or tint."""
    return 'photonlm.light_groups["%s"].%s' % (layer, prop)


def sync_settings(scene, layers):
    """Give every layer a strength and tint entry on the scene (1 and white for a new one; kept for a
    group that had one, with its animation)."""
    groups = scene.photonlm.light_groups
    for layer in layers:
        if groups.get(layer) is None:
            item = groups.add()
            item.name = layer
            item.strength = 1.0
            item.tint = (1.0, 1.0, 1.0)


def mix_group(scene, layers):
    """The node group mixing `layers` (see the module text), made or remade for them."""
    g = bpy.data.node_groups.get(MIX_GROUP)
    key = ",".join(layers)
    if g is not None and g.get(LAYERS_KEY) == key and g.get(SCENE_KEY) == scene.name:
        return g
    if g is None:
        g = bpy.data.node_groups.new(MIX_GROUP, 'ShaderNodeTree')
    if g.animation_data is not None:
        g.animation_data_clear()
    g.nodes.clear()
    compat.set_group_inputs(g, [(layer, 'NodeSocketColor') for layer in layers])
    compat.set_group_outputs(g, [("Color", 'NodeSocketColor')])
    g[TAG] = 1
    g[LAYERS_KEY] = key
    g[SCENE_KEY] = scene.name
    _build(g, scene, layers)
    return g


def _build(g, scene, layers):
    nodes, links = g.nodes, g.links
    gin = nodes.new('NodeGroupInput')
    gout = nodes.new('NodeGroupOutput')
    gin.location = (-600.0, 0.0)
    total = None
    for i, layer in enumerate(layers):
        item = scene.photonlm.light_groups.get(layer)
        y = -220.0 * i
        strength = nodes.new('ShaderNodeValue')
        strength.name = strength.label = "strength " + layer
        strength.location = (-600.0, y - 120.0)
        strength.outputs[0].default_value = item.strength if item is not None else 1.0
        tint = nodes.new('ShaderNodeRGB')
        tint.name = tint.label = "tint " + layer
        tint.location = (-800.0, y - 120.0)
        tint.outputs[0].default_value = tuple(item.tint if item is not None else (1.0, 1.0, 1.0)) + (1.0,)
        scaled = _vector_math(nodes, 'SCALE', (-400.0, y - 60.0))
        links.new(tint.outputs[0], scaled.inputs[0])
        links.new(strength.outputs[0], scaled.inputs['Scale'])
        weighted = _vector_math(nodes, 'MULTIPLY', (-200.0, y))
        links.new(gin.outputs[i], weighted.inputs[0])
        links.new(scaled.outputs['Vector'], weighted.inputs[1])
        if total is None:
            total = weighted.outputs['Vector']
        else:
            add = _vector_math(nodes, 'ADD', (0.0, y))
            links.new(total, add.inputs[0])
            links.new(weighted.outputs['Vector'], add.inputs[1])
            total = add.outputs['Vector']
        _drive(g, 'nodes["%s"].outputs[0].default_value' % strength.name, -1, scene, settings_path(layer, "strength"))
        for k in range(3):
            _drive(g, 'nodes["%s"].outputs[0].default_value' % tint.name, k, scene, settings_path(layer, "tint"), k)
    gout.location = (240.0, 0.0)
    if total is not None:
        links.new(total, gout.inputs[0])


def _vector_math(nodes, operation, location):
    n = nodes.new('ShaderNodeVectorMath')
    n.operation = operation
    n.location = location
    return n


def _drive(tree, path, index, scene, source, source_index=None):
    """A driver on tree's `path` (array element `index`, -1: a single value) giving the scene's
    property `source` (its element source_index)."""
    fcurve = tree.driver_add(path) if index < 0 else tree.driver_add(path, index)
    driver = fcurve.driver
    driver.type = 'AVERAGE'
    var = driver.variables.new()
    var.name = "value"
    var.type = 'SINGLE_PROP'
    target = var.targets[0]
    target.id_type = 'SCENE'
    target.id = scene
    target.data_path = source if source_index is None else "%s[%d]" % (source, source_index)
    return fcurve


def layer_image_name(base, layer):
    """The image of a layer of the lightmap image `base` (<object>_lightmap, a page's)."""
    return "%s.%s" % (base, layer)


def layer_file(path, layer):
    """The file of a layer beside the lightmap file `path` (..._lightmap.exr): ..._lightmap.<layer>.exr,
    as `photonlm bake` names it."""
    stem = path[:-len(".exr")] if path.endswith(".exr") else path
    return "%s.%s.exr" % (stem, layer)
