"""What a refused or failed bake must leave as it was: a snapshot of the Blender data a bake may
touch (images and their pixels, materials' nodes and links, meshes' UV maps, objects' modifiers,
the scene's statistics) and of the files in a folder, and a readable list of differences."""
import hashlib
import os

import bpy
import numpy as np


def _digest(array):
    return hashlib.sha1(np.ascontiguousarray(array).tobytes()).hexdigest()


def _image(image):
    w, h = image.size
    px = np.empty(w * h * image.channels, np.float32) if w and h else np.empty(0, np.float32)
    if w and h:
        image.pixels.foreach_get(px)
    return (image.filepath, tuple(image.size), image.colorspace_settings.name, _digest(px))


def _material(mat):
    if mat.node_tree is None:
        return None
    nt = mat.node_tree
    nodes = sorted((n.name, n.bl_idname, str(n.get("photonlm")), getattr(n, "is_active_output", None),
                    getattr(getattr(n, "image", None), "name", None)) for n in nt.nodes)
    links = sorted((l.from_node.name, l.from_socket.identifier, l.to_node.name, l.to_socket.identifier)
                   for l in nt.links)
    return nodes, links, str(nt.get("photonlm_original_output"))


def _mesh(mesh):
    layers = []
    for layer in mesh.uv_layers:
        a = np.empty(len(mesh.loops) * 2, np.float32)
        layer.data.foreach_get("uv", a)
        layers.append((layer.name, layer.active, layer.active_render, _digest(a)))
    return layers


def _files(folder):
    out = {}
    if folder and os.path.isdir(folder):
        for name in sorted(os.listdir(folder)):
            path = os.path.join(folder, name)
            if os.path.isfile(path):
                with open(path, "rb") as f:
                    out[name] = (os.path.getmtime(path), hashlib.sha1(f.read()).hexdigest())
    return out


def snapshot(folder=None):
    """The state a bake may change. folder: the lightmap folder whose files to include."""
    scene = bpy.context.scene
    stats = scene.get("photonlm_last_bake")
    return {
        "images": {im.name: _image(im) for im in bpy.data.images},
        "materials": {m.name: _material(m) for m in bpy.data.materials},
        "meshes": {m.name: _mesh(m) for m in bpy.data.meshes},
        "objects": {o.name: tuple(md.name for md in o.modifiers) for o in bpy.data.objects},
        "stats": dict(stats) if stats is not None else None,
        "files": _files(folder),
    }


def differences(before, after):
    """Lines naming what differs between two snapshots ([] when nothing)."""
    lines = []
    for key in before:
        a, b = before[key], after[key]
        if isinstance(a, dict) and isinstance(b, dict) and key != "stats":
            for name in sorted(set(a) | set(b)):
                if name not in a:
                    lines.append("%s: '%s' added" % (key, name))
                elif name not in b:
                    lines.append("%s: '%s' removed" % (key, name))
                elif a[name] != b[name]:
                    lines.append("%s: '%s' changed" % (key, name))
        elif a != b:
            lines.append("%s changed" % key)
    return lines
