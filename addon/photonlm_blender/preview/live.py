"""The lightmaps shown in the viewport while a modal bake runs.

    live = LivePreview(job, interval)    # main thread, before the worker starts
    job.run(progress, preview=live.take, preview_interval=interval)   # worker thread
    live.apply(context)                  # main thread, on each timer tick
    live.end(success)                    # main thread, once the worker has returned

The engine calls take() on the worker thread at its check points, at most every `interval`
seconds (photonlm.h plm_bake_with_preview); take() copies each baked object's current lightmap
into numpy arrays and leaves them for the main thread (no bpy there). While no 3D viewport shows
materials (Material Preview or Rendered; apply() looks on each tick) take() copies nothing. apply() writes the latest
copy into an in-memory float image per object ("PhotonLM live <object>", tagged
image[wiring.TAG] = LIVE_TAG) and, the first time, points each baked material's preview
at it: a material wired by an earlier bake gets the live image on its lightmap Image Texture
node, one without wiring gets the preview nodes (wiring.wire_material, no heat map), and
both show the Lightmaps output (a material wired with light groups or directional lightmaps
reads the live image instead of its layers or SH bands until the bake ends). What each material
was (its lightmap image, whether it was wired, which outputs were active, the remembered
original output) is kept first.

end(success=False) (cancel, error) puts every material back as it was and removes the live
images: nothing of the bake is left. end(success=True) comes after BakeJob.finish() has wired
the final images: it removes the live images (and restores any material finish() did not
rewire).
"""
import threading

import bpy
import numpy as np

from .. import compat
from ..writeback import wiring

LIVE_TAG = "live"
IMAGE_PREFIX = "PhotonLM live "


class LivePreview:
    def __init__(self, job, interval):
        self.interval = float(interval)
        # mesh id -> object name for every baked object (the worker reads this, never bpy).
        self._targets = {b.mesh_id: b.object_name for b in job.manifest.baked}
        self._owners = _material_owners(job.manifest.baked)  # material name -> object name
        self._lock = threading.Lock()
        self._pending = None   # (photons, {object name: (h, w, 3) float32}) not yet shown
        self._saved = {}       # material name -> what it was (see _save)
        self._images = {}      # object name -> image name
        self.refreshes = 0     # snapshots written into the images
        self.photons = 0       # photons of the latest one shown
        self.watched = True    # a viewport shows materials (set by the main thread, read by take())

    # -- worker thread: numpy only -----------------------------------------------------------
    def take(self, preview):
        """photonlm.Scene.bake's preview callable: copy every baked object's lightmap (nothing
        while no viewport shows materials)."""
        if not self.watched:
            return True
        maps = {}
        for mesh_id, name in self._targets.items():
            rgb = preview.lightmap(mesh_id)
            if rgb is not None:
                maps[name] = rgb
        with self._lock:
            self._pending = (preview.photons, maps)
        return True

    # -- main thread -------------------------------------------------------------------------
    def apply(self, context):
        """Show the latest snapshot, if a new one came; True when the images changed."""
        self.watched = watched(context)
        with self._lock:
            pending, self._pending = self._pending, None
        if pending is None:
            return False
        photons, maps = pending
        for name, rgb in maps.items():
            image = self._image(name, rgb.shape[1], rgb.shape[0])
            px = np.ones(rgb.shape[:2] + (4,), np.float32)
            px[..., :3] = rgb
            image.pixels.foreach_set(px.ravel())
            image.update()
        if not self._saved:
            self._wire(context)
        self.refreshes += 1
        self.photons = photons
        for area in context.screen.areas if context.screen else ():
            if area.type == 'VIEW_3D':
                area.tag_redraw()
        return True

    def end(self, success):
        """After the worker returned: restore the materials (all of them unless success, else
        those still showing a live image) and remove the live images."""
        live = set(self._images.values())
        for mat_name, saved in self._saved.items():
            try:
                mat = bpy.data.materials.get(mat_name)
                if mat is None or mat.node_tree is None:
                    continue
                node = _image_node(mat)
                if not success or node is None or (node.image is not None and node.image.name in live):
                    _restore(mat, saved)
            except ReferenceError:  # the earlier image was removed meanwhile: nothing to point back to
                pass
        self._saved = {}
        for image_name in live:
            image = bpy.data.images.get(image_name)
            if image is not None and image.get(wiring.TAG) == LIVE_TAG:
                bpy.data.images.remove(image)
        self._images = {}

    def _image(self, object_name, width, height):
        image = bpy.data.images.get(self._images.get(object_name, ""))
        if image is not None and tuple(image.size) == (width, height):
            return image
        image = bpy.data.images.new(IMAGE_PREFIX + object_name, width, height, alpha=False, float_buffer=True)
        image[wiring.TAG] = LIVE_TAG
        image.colorspace_settings.name = 'Non-Color'  # before the pixels: changing it regenerates them
        image.alpha_mode = 'NONE'
        self._images[object_name] = image.name
        return image

    def _wire(self, context):
        engine = context.scene.render.engine
        for mat_name, object_name in self._owners.items():
            mat = bpy.data.materials.get(mat_name)
            image = bpy.data.images.get(self._images.get(object_name, ""))
            if mat is None or image is None or not compat.uses_nodes(mat):
                continue
            node = _image_node(mat)
            uv = next((n for n in mat.node_tree.nodes if n.get(wiring.TAG) == "uv"), None)
            if node is not None and uv is not None and uv.bl_idname != 'ShaderNodeUVMap':
                continue  # wired to an orientation lightmap: shown as it was until the bake ends
            self._saved[mat_name] = _save(mat)
            if node is not None:
                node.image = image
                _feed_multiply(mat, from_groups=False)  # the live image, not the layers or SH bands
            else:
                wiring.wire_material(mat, image, engine)  # its notes come again with the final wiring
            wiring.set_preview(mat, 'LIGHTMAP')


def watched(context):
    """Whether a 3D viewport of the window shows materials (Material Preview or Rendered)."""
    screens = [w.screen for w in context.window_manager.windows] if context.window_manager else []
    return any(space.type == 'VIEW_3D' and space.shading.type in ('MATERIAL', 'RENDERED')
               for screen in screens if screen is not None for area in screen.areas
               for space in area.spaces[:1])


def _material_owners(baked):
    """Material name -> the baked object whose lightmap it shows (the first by name, as
    BakeJob._wire chooses)."""
    owners = {}
    for b in sorted(baked, key=lambda b: b.object_name):
        for name in b.material_names:
            if name is not None:
                owners.setdefault(name, b.object_name)
    return owners


def _image_node(mat):
    """The Image Texture node of a material's lightmap preview, or None if it is not wired."""
    if not wiring.is_wired(mat):
        return None
    return next((n for n in mat.node_tree.nodes if n.get(wiring.TAG) == "image"), None)


def _save(mat):
    tree = mat.node_tree
    node = _image_node(mat)
    return dict(wired=node is not None, image=node.image if node is not None else None,
                active=[n.name for n in tree.nodes if n.bl_idname == 'ShaderNodeOutputMaterial'
                        and n.is_active_output],
                remembered=tree.get(wiring.ORIGINAL_OUTPUT_KEY))


def _feed_multiply(mat, from_groups):
    """Feed the preview's Multiply from what the last bake's wiring feeds it with (from_groups):
    the directional lightmap's node group or the light groups' mix, where the material has one; or
    from its lightmap Image Texture (the live image, which has neither layers nor directions)."""
    tree = mat.node_tree
    roles = ("image", "light_groups", "directional", "multiply")
    tagged = {n.get(wiring.TAG): n for n in tree.nodes if n.get(wiring.TAG) in roles}
    wired = tagged.get("directional") or tagged.get("light_groups")
    source = wired if from_groups else tagged.get("image")
    if source is None or "multiply" not in tagged or wired is None:
        return
    _, _, b, _ = compat.mix_color_sockets(tagged["multiply"])
    tree.links.new(source.outputs['Color'], b)


def _restore(mat, saved):
    tree = mat.node_tree
    if saved["wired"]:
        node = _image_node(mat)
        if node is not None:
            node.image = saved["image"]
            _feed_multiply(mat, from_groups=True)
    else:
        wiring.remove_wiring(mat)
    outputs = [n for n in tree.nodes if n.bl_idname == 'ShaderNodeOutputMaterial']
    for n in outputs:
        if n.name not in saved["active"]:
            n.is_active_output = False
    for n in outputs:
        if n.name in saved["active"]:
            n.is_active_output = True
    if saved["remembered"] is None:
        if wiring.ORIGINAL_OUTPUT_KEY in tree:
            del tree[wiring.ORIGINAL_OUTPUT_KEY]
    else:
        tree[wiring.ORIGINAL_OUTPUT_KEY] = saved["remembered"]
