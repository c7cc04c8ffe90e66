"""Lightmap atlases (scene.photonlm.lightmap_layout = 'ATLAS'): the baked objects' lightmaps
packed into a few square pages.

Each object is baked as in one-per-object mode, at its own resolution (export/resolution.py's ResolutionRule:
one texel density for all, no power-of-two rounding), then its block of texels is copied into a
page at the place uv/atlas_pack.py finds for it, with a ring of atlas_pad texels around it that
repeats the block's edge texels. Per page the bake writes
    <scene>_atlas_<k>_lightmap.exr   R, G, B, error, hits (as a one-object lightmap file)
    <scene>_atlas_<k>_error.exr      the heat map of its relative errors
and loads them as images of the same names; with light groups each layer has pages of its own,
<scene>_atlas_<k>_lightmap.<group>.exr (writeback/lightgroups.py), and directional lightmaps their
L1 bands' pages <scene>_atlas_<k>_lightmap_sh1.exr .. _sh3.exr (writeback/directional.py). Each
object gets
    the UV map 'PhotonLM Atlas': its lightmap UVs moved into its block, u' = u su + ou,
        v' = v sv + ov. The mesh holding the lightmap map (the object's own, or the helper mesh of
        an automatic map that a Data Transfer modifier brings, uv/uvmaps.py) holds a copy of it as
        'PhotonLM Atlas' (the object's own mesh then an empty one for Data Transfer to fill), and a
        UV Warp modifier 'PhotonLM Atlas UV' of the object's moves it into the block, so that
        objects sharing a mesh (linked duplicates, or copies sharing one helper) each get their own
        place;
    custom properties photonlm_atlas_page (the page image's name), photonlm_atlas_file (the page
        file, relative to the .blend where possible) and photonlm_atlas_scale_offset (su, sv, ou, ov),
and its materials' preview reads the page through 'PhotonLM Atlas'. The scene's ID property
photonlm_atlas records the layout (page size, pad, pages, each object's block).

Bake Selected keeps the layout: a selected object whose block keeps its size is written into its
old place; one whose size changed, or that was in no page, goes to free space in a page (a new
page when none has room); every other block and page stays as it was (pages are read back from
their files). Bake Lightmaps (all objects) packs everything anew. Objects baked later into lightmaps of their
own lose their atlas UV map and properties (forget).
"""
import os

import bpy
import numpy as np

from .. import bridge
from ..export import meshes
from ..export.meshes import LIGHTMAP_UV
from ..export.resolution import atlas_pad
from ..export.scene import safe_file_name
from ..uv import atlas_pack, uvmaps
from . import directional, lightgroups, wiring
from .images import error_image_pixels, load_image, relative_error, write_error_exr

ATLAS_UV = "PhotonLM Atlas"
LAYOUT_KEY = "photonlm_atlas"                        # on the scene: the layout of the last atlas bake
PAGE_KEY = "photonlm_atlas_page"                     # on an object: its page image's name
FILE_KEY = "photonlm_atlas_file"                     # on an object: its page file
SCALE_OFFSET_KEY = "photonlm_atlas_scale_offset"     # on an object: (su, sv, ou, ov)


class AtlasError(Exception):
    """An atlas bake that cannot be done; the message is for the user."""


def is_atlas(scene):
    return getattr(scene.photonlm, "lightmap_layout", 'OBJECT') == 'ATLAS'


def page_size(scene):
    return int(scene.photonlm.atlas_size)


def page_name(scene, k):
    return "%s_atlas_%d" % (safe_file_name(scene.name), k)


def _layout(scene):
    """The last atlas layout of the scene as a plain dict, or None."""
    layout = scene.get(LAYOUT_KEY)
    return layout.to_dict() if layout is not None else None


def usable_layout(scene, out_dir=None):
    """The scene's last atlas layout when Bake Selected can add to it (same page size and margin,
    every page file still there), else None; and why not (a text for the user)."""
    layout = _layout(scene)
    if layout is None:
        return None, "the scene has no atlas yet"
    if int(layout.get("size", 0)) != page_size(scene) or int(layout.get("pad", -1)) != \
            atlas_pad(scene.photonlm):
        return None, "the atlas was baked with another page size or margin"
    for path in layout.get("files", ()):
        if not os.path.isfile(bpy.path.abspath(path)):
            return None, "its page file '%s' is missing" % path
    return layout, ""


def check(scene, baked, selected_only):
    """Before the bake: refuse blocks too large for a page (naming the objects) and a Bake Selected
    without an atlas to add to. Raises AtlasError."""
    size, pad = page_size(scene), atlas_pad(scene.photonlm)
    large = ["'%s' (%d x %d)" % (b.object_name, b.width, b.height) for b in baked
             if b.width + 2 * pad > size or b.height + 2 * pad > size]
    if large:
        raise AtlasError("lightmap%s of %s %s too large for a %d x %d atlas page with a margin of %d texels "
                         "on each side of %s: lower %s Resolution (Auto fits it), or choose a larger Page Size"
                         % ("s" if len(large) > 1 else "", ", ".join(large), "are" if len(large) > 1 else "is",
                            size, size, pad, "each" if len(large) > 1 else "it",
                            "their" if len(large) > 1 else "its"))
    if selected_only:
        layout, why = usable_layout(scene)
        if layout is None:
            raise AtlasError("Bake Selected adds to the scene's atlas, but %s: bake all objects first "
                             "(Bake Lightmaps)" % why)


def _blank(size):
    return (np.zeros((size, size, 3), np.float32), np.zeros((size, size), np.float32),
            np.zeros((size, size), np.float32))


def paste(page, lm, p, pad):
    """Copy lightmap lm (rgb, error, hits) into page arrays (rgb, error, hits) at Placement p, with
    its edge texels repeated over `pad` texels around it (hits 0 there: no photon landed)."""
    rgb, err, hits = page
    y0, y1, x0, x1 = p.y - pad, p.y + p.h + pad, p.x - pad, p.x + p.w + pad
    rgb[y0:y1, x0:x1] = np.pad(lm.rgb, ((pad, pad), (pad, pad), (0, 0)), mode="edge")
    err[y0:y1, x0:x1] = np.pad(lm.error, pad, mode="edge")
    hits[y0:y1, x0:x1] = np.pad(lm.hits, pad, mode="constant")


def _placements(scene, names, sizes, selected_only, layout):
    """(placements by object name, page count, pages that change) for the blocks `sizes` of objects
    `names`: packed anew, or added to `layout` (Bake Selected)."""
    size, pad = page_size(scene), atlas_pad(scene.photonlm)
    if not selected_only:
        placed = atlas_pack.pack(sizes, size, pad)
        count = atlas_pack.page_count(placed)
        return dict(zip(names, placed)), count, set(range(count))
    old = {n: atlas_pack.Placement(*b) for n, b in layout["blocks"].items()}
    out, moved = {}, []
    for n, (w, h) in zip(names, sizes):
        p = old.get(n)
        if p is not None and (p.w, p.h) == (w, h):
            out[n] = p
        else:
            moved.append((n, (w, h)))
            old.pop(n, None)
    keep = {n: p for n, p in old.items() if n not in out}
    new, count = atlas_pack.place([s for _, s in moved], list(keep.values()) + list(out.values()), size, pad,
                                  len(layout["pages"]))
    out.update(zip([n for n, _ in moved], new))
    result = dict(keep)
    result.update(out)
    return result, count, {p.page for p in out.values()}


def _write_uv(obj, scale_offset, reports):
    """The object's UV map ATLAS_UV (a copy of its lightmap UVs, in the mesh that holds them) and the
    UV Warp modifier that moves it into the object's block (see the module text)."""
    mod = uvmaps.automatic_modifier(obj)
    holders = [obj.data] if mod is None else [mod.object.data, obj.data]
    src = holders[0].uv_layers.get(LIGHTMAP_UV)
    if src is None:
        reports.warning("object '%s': no UV map '%s' to place in its atlas" % (obj.name, LIGHTMAP_UV))
        return False
    uv = meshes.loop_uv(src, len(holders[0].loops)).reshape(-1)
    for i, mesh in enumerate(holders):
        layer = mesh.uv_layers.get(ATLAS_UV)
        if layer is None:
            if len(mesh.uv_layers) >= 8:
                reports.warning("mesh '%s' already has 8 UV maps: no '%s' map for object '%s' (its atlas place "
                                "is in its custom properties)" % (mesh.name, ATLAS_UV, obj.name))
                return False
            active = mesh.uv_layers.active.name if mesh.uv_layers.active else None
            render = next((l.name for l in mesh.uv_layers if l.active_render), None)
            layer = mesh.uv_layers.new(name=ATLAS_UV, do_init=False)
            if active is not None:
                mesh.uv_layers.active = mesh.uv_layers[active]
            if render is not None:
                mesh.uv_layers[render].active_render = True
        # The helper's map is the data; the object's own mesh (Data Transfer's destination) gets zeros.
        layer.data.foreach_set("uv", uv if i == 0 else np.zeros(len(mesh.loops) * 2, np.float32))
        mesh.update()
    _place_warp(obj, scale_offset, mod)
    return True


def _place_warp(obj, scale_offset, transfer):
    """The object's UV Warp modifier: ATLAS_UV -> (uv + offset) x scale = uv su + ou (center 0), just
    after the Data Transfer modifier that brings the map, else before a last Subdivision Surface (which
    keeps GPU subdivision; an affine map commutes with subdivision's UV interpolation), else last."""
    warp = next((m for m in obj.modifiers if uvmaps.is_atlas_modifier(m)), None)
    if warp is None:
        active = obj.modifiers.active
        warp = obj.modifiers.new(uvmaps.ATLAS_MODIFIER_NAME, 'UV_WARP')
        if active is not None:
            obj.modifiers.active = active  # the user's active modifier stays active
        warp.show_expanded = False
    su, sv, ou, ov = scale_offset
    warp.uv_layer = ATLAS_UV
    warp.center = (0.0, 0.0)
    warp.scale = (su, sv)
    warp.offset = (ou / su, ov / sv)
    warp.rotation = 0.0
    warp.object_from = warp.object_to = None
    warp.vertex_group = ""
    mods = [m for m in obj.modifiers if m != warp]
    if transfer is not None:
        index = mods.index(transfer) + 1
    elif mods and mods[-1].type == 'SUBSURF':
        index = len(mods) - 1
    else:
        index = len(mods)
    uvmaps.move_modifier(obj, warp, index)


def _relative(path):
    if bpy.data.is_saved:
        try:
            return bpy.path.relpath(path)
        except ValueError:  # another drive than the .blend
            pass
    return path


def store(context, selected_only, reports, lightmaps, out_dir, pack, per_object, layers=(), layer_blocks=None,
          sh_blocks=None):
    """Pack the baked lightmaps {object name: photonlm.Lightmap} into atlas pages, write and load the
    pages, give each object its atlas UV map and properties. Returns (images, error_images, uv_maps)
    by object name for the preview wiring, the stale pages for remove_stale (after the wiring), and
    with light groups (layers: their names; layer_blocks: {object name: [(rgb, error) per layer]})
    {object name: [(layer, page layer image)]}: each layer has pages of its own,
    <page>_lightmap.<layer>, and with directional lightmaps (sh_blocks: {object name: its SH bands,
    photonlm.Result.lightmap_sh's (4, h, w, 3)}) {object name: [page band image per L1 band]}: each
    band has pages of its own, <page>_lightmap_sh<band>. Adds each object's "atlas" entry to
    per_object."""
    scene = context.scene
    size, pad = page_size(scene), atlas_pad(scene.photonlm)
    layout = usable_layout(scene)[0] if selected_only else None
    old_layout = _layout(scene)
    names = sorted(lightmaps)
    sizes = [(lightmaps[n].rgb.shape[1], lightmaps[n].rgb.shape[0]) for n in names]
    placements, count, changed = _placements(scene, names, sizes, selected_only, layout)
    plm = bridge.get()
    files = [os.path.join(out_dir, page_name(scene, k) + "_lightmap.exr") for k in range(count)]
    if layout is not None:  # pages already there keep their files
        files[:len(layout["files"])] = [bpy.path.abspath(f) for f in layout["files"]]
    page_images, error_images, layer_pages, sh_pages = [], [], [], []
    for k in range(count):
        name = page_name(scene, k)
        if layout is not None and k < len(layout["pages"]):  # a page already there keeps its name
            name = layout["pages"][k][:-len("_lightmap")]
        if k in changed:
            if layout is not None and k < len(layout["files"]):
                old = plm.read_lightmap_exr(files[k])
                page = (old.rgb, old.error, old.hits)
                if old.rgb.shape[:2] != (size, size):
                    raise AtlasError("atlas page '%s' is %d x %d, not %d x %d" % (files[k], old.rgb.shape[1],
                                                                                  old.rgb.shape[0], size, size))
            else:
                page = _blank(size)
            for n in names:
                p = placements[n]
                if p.page == k:
                    paste(page, lightmaps[n], p, pad)
            plm.write_lightmap_exr(files[k], *page)
            error_path = files[k][:-len("_lightmap.exr")] + "_error.exr"
            write_error_exr(error_path, error_image_pixels(relative_error(page[0], page[1])))
            page_images.append(load_image(name + "_lightmap", files[k], pack))
            error_image = load_image(name + "_error", error_path, pack)
        else:
            error_path = files[k][:-len("_lightmap.exr")] + "_error.exr"
            page_images.append(bpy.data.images.get(name + "_lightmap")
                               or load_image(name + "_lightmap", files[k], pack))
            error_image = bpy.data.images.get(name + "_error") or load_image(name + "_error", error_path, pack)
        error_image[wiring.TAG] = wiring.ERROR_IMAGE_TAG
        error_images.append(error_image)
        kept = layout is not None and k < len(layout["files"])  # Bake Selected adds to this page
        layer_pages.append(_layer_pages(plm, files[k], page_images[-1].name, k in changed, kept, layers,
                                        layer_blocks or {}, lightmaps, placements, k, size, pad, pack, reports))
        sh_pages.append(_sh_pages(plm, files[k], page_images[-1].name, k in changed, kept, sh_blocks, lightmaps,
                                  placements, k, size, pad, pack, reports) if sh_blocks is not None else [])

    images, errors, uv_maps, layer_images, sh_images = {}, {}, {}, {}, {}
    for n in names:
        p = placements[n]
        so = p.scale_offset(size)
        obj = bpy.data.objects.get(n)
        if obj is not None and _write_uv(obj, so, reports):
            uv_maps[n] = ATLAS_UV
        if obj is not None:
            obj[PAGE_KEY] = page_images[p.page].name
            obj[FILE_KEY] = _relative(files[p.page])
            obj[SCALE_OFFSET_KEY] = list(so)
        images[n] = page_images[p.page]
        errors[n] = error_images[p.page]
        layer_images[n] = layer_pages[p.page]
        sh_images[n] = sh_pages[p.page]
        if sh_pages[p.page]:
            per_object[n]["sh"] = [dict(band=band, image=im.name, path=directional.band_file(files[p.page], band))
                                   for band, im in zip(directional.BANDS, sh_pages[p.page])]
        per_object[n]["layers"] = {layer: dict(image=im.name, path=lightgroups.layer_file(files[p.page], layer))
                                   for layer, im in layer_pages[p.page]}
        per_object[n].update(image=page_images[p.page].name, path=files[p.page],
                             error_image=error_images[p.page].name,
                             error_path=files[p.page][:-len("_lightmap.exr")] + "_error.exr",
                             atlas=dict(page=p.page, rect=(p.x, p.y, p.w, p.h), scale_offset=so, uv_map=ATLAS_UV))
    # Objects whose block is too small for their area (capped at the page size) bake at a lower density.
    largest = size - 2 * pad
    for n in names:
        obj = bpy.data.objects.get(n)
        if obj is not None and obj.photonlm.resolution == 0 and max(sizes[names.index(n)]) >= largest:
            reports.warning("object '%s' fills a whole atlas page (its lightmap is capped at %d x %d texels): "
                                "it gets fewer texels per metre than the Texel Density; choose a larger Page Size"
                                % (n, largest, largest))
    blocks = {n: list(p) for n, p in placements.items()}
    scene[LAYOUT_KEY] = dict(size=size, pad=pad, pages=[im.name for im in page_images],
                             files=[_relative(f) for f in files], blocks=blocks, layers=",".join(layers))
    stale = []
    if old_layout is not None and not selected_only:
        stale = [(name, path) for name, path in zip(old_layout.get("pages", ()), old_layout.get("files", ()))
                 if name not in scene[LAYOUT_KEY]["pages"]]
    return images, errors, uv_maps, stale, layer_images, sh_images


def _sh_pages(plm, page_file, page_image, changed, kept, sh_blocks, lightmaps, placements, k, size, pad, pack,
              reports):
    """The L1 bands of page k: [image per band]. A changed page's bands are written (an earlier
    page's band file read first where Bake Selected adds to it), an unchanged one's kept."""
    out = []
    for band in directional.BANDS:
        path = directional.band_file(page_file, band)
        name = directional.band_image_name(page_image, band)
        if kept and not os.path.isfile(path) and band == directional.BANDS[0]:
            reports.warning("atlas page '%s' has no directional bands (it was baked without Directional): the "
                            "preview of its other objects shows half their light; bake all objects (Bake "
                            "Lightmaps)" % page_image)
        blocks = {n: _Block(bands[band], np.zeros_like(lightmaps[n].hits), lightmaps[n].hits)
                  for n, bands in sh_blocks.items()}
        image = _part_page(plm, path, name, changed, kept, blocks, placements, k, size, pad, pack)
        if image is None:
            return []
        out.append(image)
    return out


def _layer_pages(plm, page_file, page_image, changed, kept, layers, layer_blocks, lightmaps, placements, k, size,
                 pad, pack, reports):
    """The light-group layers of page k: [(layer, image)]. A changed page's layers are written (an
    earlier page's layer file read first where Bake Selected adds to it), an unchanged one's kept."""
    out = []
    for i, layer in enumerate(layers):
        path = lightgroups.layer_file(page_file, layer)
        name = lightgroups.layer_image_name(page_image, layer)
        if kept and not os.path.isfile(path):  # Bake Selected: an earlier page baked without this group
            reports.warning("atlas page '%s' has no layer '%s' (it was baked without that light group): the "
                            "preview of its other objects lacks that group's light; bake all objects (Bake "
                            "Lightmaps)" % (page_image, layer))
        blocks = {n: _Block(*b[i], lightmaps[n].hits) for n, b in layer_blocks.items()}
        image = _part_page(plm, path, name, changed, kept, blocks, placements, k, size, pad, pack)
        if image is not None:
            out.append((layer, image))
    return out


def _part_page(plm, path, name, changed, kept, blocks, placements, k, size, pad, pack):
    """One part (a light-group layer, an SH band) of page k as image `name` from file `path`: an
    unchanged page's as it is (None if neither image nor file is there); a changed page's written
    from the blocks ({object: _Block}) of its objects, over the earlier file where Bake Selected
    keeps the page's other objects."""
    if not changed:
        image = bpy.data.images.get(name)
        if image is None and os.path.isfile(path):
            image = load_image(name, path, pack)
        return image
    page = _blank(size)
    if kept and os.path.isfile(path):
        old = plm.read_lightmap_exr(path)
        if old.rgb.shape[:2] == (size, size):
            page = (old.rgb, old.error, old.hits)
    for n, block in blocks.items():
        p = placements[n]
        if p.page == k:
            paste(page, block, p, pad)
    plm.write_lightmap_exr(path, *page)
    return load_image(name, path, pack)


class _Block:
    """A layer's block as paste() takes it (the lightmap's hits: a layer has none of its own)."""

    def __init__(self, rgb, error, hits):
        self.rgb, self.error, self.hits = rgb, error, hits


def forget(names):
    """Objects baked into lightmaps of their own: remove their atlas UV map and properties, which
    would point into an atlas that no longer holds their light."""
    for n in names:
        obj = bpy.data.objects.get(n)
        if obj is None or PAGE_KEY not in obj:
            continue
        for key in (PAGE_KEY, FILE_KEY, SCALE_OFFSET_KEY):
            obj.pop(key, None)
        mod = uvmaps.automatic_modifier(obj)
        for mesh in [obj.data] + ([mod.object.data] if mod is not None else []):
            layer = mesh.uv_layers.get(ATLAS_UV)
            if layer is not None:
                mesh.uv_layers.remove(layer)
        for warp in [m for m in obj.modifiers if uvmaps.is_atlas_modifier(m)]:
            obj.modifiers.remove(warp)



def object_lightmap(obj):
    """Where an object's baked light is, as the write-back keeps it: (image, UV map name), its atlas
    page (the image named by the object's PAGE_KEY) read through ATLAS_UV, else its own image
    <object>_lightmap read through the lightmap UV map; (None, None) for an object without one."""
    page = obj.get(PAGE_KEY)
    if page:
        image = bpy.data.images.get(page)
        if image is not None:
            return image, ATLAS_UV
    image = bpy.data.images.get(obj.name + "_lightmap")
    return (image, LIGHTMAP_UV) if image is not None else (None, None)

def remove_stale(stale):
    """Remove the pages of an earlier, larger atlas (after the materials are wired to the new pages):
    their files, and their images where nothing uses them."""
    for name, path in stale:
        layer_images = [im.name for im in bpy.data.images if im.name.startswith(name + ".")]
        sh_images = [directional.band_image_name(name, band) for band in directional.BANDS]
        for im_name in [name, name[:-len("_lightmap")] + "_error"] + layer_images + sh_images:
            im = bpy.data.images.get(im_name)
            if im is not None and im.users == 0:
                bpy.data.images.remove(im)
        path = bpy.path.abspath(path)
        layer_files = [lightgroups.layer_file(path, im_name[len(name) + 1:]) for im_name in layer_images]
        sh_files = [directional.band_file(path, band) for band in directional.BANDS]
        for f in [path, path[:-len("_lightmap.exr")] + "_error.exr"] + layer_files + sh_files:
            if os.path.isfile(f):
                os.remove(f)
