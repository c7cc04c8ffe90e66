"""Measures the automatic lightmap UVs of the artist's room (blend_tests/scenes.py: artist_room)
as the engine receives them: the add-on makes the missing 'lightmap' UV maps and exports the
scene into a recorder; subdivision cages are refined with the engine's own refinement
(photonlm.subdiv_refine). Per object: overlapping texels (the engine's count), texels shared
by two islands, zero-area and outside-square triangles, folded triangles, the smallest island
margin in texels and the share of the map the islands cover; then a short bake lists the
engine's warnings.

    PHOTONLM_LIBRARY=build-uv/lib/libphotonlm.so blender -b --factory-startup \
        --python docs/measure_lightmap_uvs.py -- [--native-subdivision 0|1] [--add-on-source DIR]

--add-on-source measures another checkout's add-on (e.g. an older commit in a git worktree);
the room and the measurements always come from this checkout.
"""
import argparse
import importlib.util
import os
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ap = argparse.ArgumentParser()
ap.add_argument("--native-subdivision", type=int, default=1)
ap.add_argument("--add-on-source", default=ROOT)
ap.add_argument("--bake", type=int, default=1)
args = ap.parse_args(argv)

os.environ["PHOTONLM_SOURCE_DIR"] = args.add_on_source
sys.path.insert(0, os.path.join(ROOT, "blend_tests"))
import scenes  # noqa: E402

spec = importlib.util.spec_from_file_location("uvcheck", os.path.join(ROOT, "addon", "photonlm_blender", "uv", "uvcheck.py"))
uvcheck = importlib.util.module_from_spec(spec)
spec.loader.exec_module(uvcheck)


class Recorder:
    """Takes photonlm.Scene's calls; keeps the meshes."""

    def __init__(self):
        self.meshes = []
        self._next = 0

    def add_mesh(self, name, positions, triangles, lightmap_uv=None, material_ids=None, resolution=0):
        self.meshes.append(dict(name=name, pos=np.asarray(positions)[np.asarray(triangles, np.int64)],
                                uv=lightmap_uv, res=resolution, subdiv=None))
        return len(self.meshes) - 1

    def add_subdiv_mesh(self, name, positions, face_sizes, face_indices, level, lightmap_uv=None, material_ids=None,
                        crease_edges=None, crease_weights=None, resolution=0):
        import photonlm
        pos, tri, uv = photonlm.subdiv_refine(positions, face_sizes, face_indices, level, lightmap_uv=lightmap_uv,
                                              crease_edges=crease_edges, crease_weights=crease_weights)
        self.meshes.append(dict(name=name, pos=pos[tri.astype(np.int64)], uv=uv, res=resolution, subdiv=level))
        return len(self.meshes) - 1

    def close(self):
        pass

    def __getattr__(self, attr):
        def call(*a, **k):
            self._next += 1
            return self._next
        return call


def main():
    plm = scenes.setup_paths()
    from photonlm_blender import bridge
    from photonlm_blender.export import scene as export
    from photonlm_blender.uv import uvmaps
    bridge.get()
    scenes.clear_scene()
    out = scenes.out_dir("measure_uvs")
    scenes.artist_room(out)
    scene = bpy.context.scene
    scene.photonlm.native_subdivision = bool(args.native_subdivision)
    scene.photonlm.output_dir = out
    reports = export.Reports()
    t0 = time.perf_counter()
    uvmaps.ensure_for_scene(bpy.context, export.lightmap_objects(bpy.context), reports)
    t_uv = time.perf_counter() - t0
    rec = Recorder()
    result = export.export_scene(bpy.context, type("F", (), {"Scene": lambda self=None: rec})(), reports)
    result.texture_files.cleanup()
    print("add-on: %s, native subdivision %s, lightmap UVs made in %.2f s"
          % (plm.__file__, bool(args.native_subdivision), t_uv))
    print("| object | lightmap | triangles | islands | overlap texels | shared texels | zero-area | outside | "
          "folded | margin (texels) | map used |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for m in sorted(rec.meshes, key=lambda m: m["name"]):
        if m["uv"] is None or not m["res"]:
            continue
        s = uvcheck.analyse(m["uv"], int(m["res"]), m["pos"])
        print("| %s%s | %d | %d | %d | %d | %d | %d | %d | %d | %s | %.0f %% |"
              % (m["name"], " (cage, level %d)" % m["subdiv"] if m["subdiv"] else "", m["res"], s["triangles"],
                 s["islands"], s["overlap_texels"], s["shared_texels"], s["zero_area"], s["outside"], s["flipped"],
                 ("%.1f" % s["margin"]) if s["margin"] < uvcheck.MARGIN_CAP else ">= %g" % uvcheck.MARGIN_CAP,
                 100 * s["utilisation"]), flush=True)
    for level, text in reports.items:
        if "UV" in text or "subdivi" in text:
            print("report:", text)
    if args.bake:
        last = scenes.photonlm_bake(2_000_000, 8, seed=1, target_error=0.0, direct_samples=16)
        for w in last["warnings"]:
            print("engine:", w)
        print("bake: %.1f s, %d engine warnings" % (last["wall_seconds"], len(last["warnings"])))
        inside, outside = window_wall(bpy.data.objects["Walls"], np.asarray(last["objects"]["Walls"]["rgb"]))
        print("window wall: inside %.4f, outside %.4f, inside / outside %.3f" % (inside, outside, inside / outside))


def window_wall(walls, rgb):
    """Area-weighted mean lightmap value over the inside (x = 3) and outside (x = 3.2) of the
    sunlit window wall, sampled at points inside each of their triangles."""
    pos, uv = scenes.evaluated_lightmap_triangles(walls)
    n = np.cross(pos[:, 1] - pos[:, 0], pos[:, 2] - pos[:, 0])
    area = 0.5 * np.linalg.norm(n, axis=1)
    nx = np.abs(n[:, 0]) / np.maximum(2 * area, 1e-30)
    cx = pos[:, :, 0].mean(axis=1)
    h, w = rgb.shape[:2]
    k = 8
    bary = np.array([(i + 1 / 3, j + 1 / 3) for i in range(k) for j in range(k - i)]) / k
    bary = np.column_stack([1 - bary.sum(axis=1), bary])
    out = []
    for x in (3.0, 3.2):
        sel = (nx > 0.99) & (np.abs(cx - x) < 0.01) & (area > 1e-6)
        pts = np.einsum("sk,tkd->tsd", bary, uv[sel])
        ix = np.clip((pts[..., 0] * w).astype(int), 0, w - 1)
        iy = np.clip((pts[..., 1] * h).astype(int), 0, h - 1)
        vals = rgb[iy, ix].mean(axis=-1).mean(axis=1)
        out.append(float((vals * area[sel]).sum() / area[sel].sum()))
    return out


main()
