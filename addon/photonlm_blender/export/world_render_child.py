"""Run by export/world.py's render_world in a separate `blender -b --factory-startup` process: renders
one world, read from a library .blend, into an equirectangular map with Cycles and saves its
pixels as a .npy file ((H, W, 3) float32 radiance, top row first). Runs apart from the user's
session so that nothing there changes: no scene, camera or image is created in it and its
Render Result keeps the user's last render.

Arguments after "--": library.blend world_name out.npy width height samples [sky_node]
With sky_node (a Sky Texture's name) the world is rendered a second time with that node's sun disc
off (16 samples a pixel), into out_sky.npy: the disc becomes a sun lamp of its own
(export/world.py, split_sun).
"""
import math
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
import compat  # noqa: E402  (the add-on's compat.py, a folder up: run as a script, not as a package)

# Cycles' Light Path outputs for a diffuse bounce that escapes to the world: a world that shows the
# camera something else (Is Camera Ray) is rendered as the lighting sees it.
DIFFUSE_RAY = {"Is Camera Ray": 0.0, "Is Shadow Ray": 0.0, "Is Diffuse Ray": 1.0, "Is Glossy Ray": 0.0,
               "Is Singular Ray": 0.0, "Is Reflection Ray": 1.0, "Is Transmission Ray": 0.0,
               "Is Volume Scatter Ray": 0.0, "Ray Length": 1e10, "Ray Depth": 1.0, "Diffuse Depth": 1.0,
               "Glossy Depth": 0.0, "Transparent Depth": 0.0, "Transmission Depth": 0.0}


def as_diffuse_ray(node_tree):
    """Replaces the Light Path nodes of a node tree (and of the groups it uses) by constants."""
    for node in list(node_tree.nodes):
        if node.bl_idname == 'ShaderNodeGroup' and node.node_tree is not None:
            as_diffuse_ray(node.node_tree)
        if node.bl_idname != 'ShaderNodeLightPath':
            continue
        for out in node.outputs:
            if not out.is_linked:
                continue
            value = node_tree.nodes.new('ShaderNodeValue')
            value.outputs[0].default_value = DIFFUSE_RAY.get(out.name, 0.0)
            for link in list(out.links):
                node_tree.links.new(value.outputs[0], link.to_socket)
        node_tree.nodes.remove(node)


def main():
    args = sys.argv[sys.argv.index("--") + 1:]
    lib, name, out, width, height, samples = args[:6]
    sky_node = args[6] if len(args) > 6 else None
    with bpy.data.libraries.load(lib, link=False) as (src, dst):
        dst.worlds = [name]
    world = dst.worlds[0]
    if compat.uses_nodes(world):
        as_diffuse_ray(world.node_tree)
    scene = bpy.context.scene
    for obj in list(scene.collection.all_objects):
        bpy.data.objects.remove(obj)
    scene.world = world
    r = scene.render
    r.engine = 'CYCLES'
    r.resolution_x, r.resolution_y = int(width), int(height)
    r.resolution_percentage = 100
    r.use_border = False
    r.film_transparent = False
    r.use_compositing = False
    r.use_sequencer = False
    r.image_settings.file_format = 'OPEN_EXR'
    r.image_settings.color_depth = '32'
    r.image_settings.color_mode = 'RGB'
    r.filepath = os.path.splitext(out)[0] + ".exr"
    scene.view_settings.view_transform = 'Standard'
    scene.view_settings.look = 'None'
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    c = scene.cycles
    c.device = 'CPU'
    # Up to `samples` per pixel, adaptively: the smooth sky stops at 16, the pixels a sun disc
    # crosses go on until its share of each is found (measured: the sun's energy within 0.1 % of a
    # fixed 1024 samples).
    c.samples = int(samples)
    c.use_adaptive_sampling = True
    c.adaptive_threshold = 0.01
    c.adaptive_min_samples = 16
    c.use_denoising = False
    c.seed = 0
    c.pixel_filter_type = 'BOX'  # each pixel the mean radiance over its solid angle: a small sun keeps its energy
    c.filter_width = 1.0
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    cam = bpy.data.cameras.new("photonlm world camera")
    cam.type = 'PANO'
    compat.set_equirectangular(cam)
    obj = bpy.data.objects.new("photonlm world camera", cam)
    # This orientation puts the image's centre along +X and its top row at +Z (measured: a render
    # of an Environment Texture gives back its image pixel for pixel).
    obj.rotation_euler = (math.pi / 2, 0.0, -math.pi / 2)
    scene.collection.objects.link(obj)
    scene.camera = obj
    render(r, out)
    if sky_node is not None:
        world.node_tree.nodes[sky_node].sun_disc = False
        # Without the disc the sky is smooth: 16 samples a pixel (measured on a Nishita sky: 0.05 %
        # RMS from the adaptive render, the same irradiance on an up-facing plane to 1e-6; 2 s less).
        c.samples = min(int(samples), 16)
        r.filepath = os.path.splitext(out)[0] + "_sky.exr"
        render(r, os.path.splitext(out)[0] + "_sky.npy")


def render(r, out):
    """Renders the scene into r.filepath (an EXR) and saves its pixels as `out`."""
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(r.filepath)
    image.colorspace_settings.name = compat.linear_colorspace(image)
    w, h = image.size
    px = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    np.save(out, np.ascontiguousarray(px.reshape(h, w, 4)[::-1, :, :3]))
    bpy.data.images.remove(image)


if __name__ == "__main__":
    try:
        main()
    except Exception as e:  # the parent reads the exit code and this line
        print("photonlm world render failed: %s" % e, file=sys.stderr)
        sys.exit(1)
