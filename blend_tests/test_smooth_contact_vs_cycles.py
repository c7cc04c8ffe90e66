"""Smooth shading and faces in contact: photonlm vs a converged Cycles bake.

Scene: a 4 m floor (fixed lightmap layout), a flat-shaded 0.6 m box standing on it, a
flat-shaded 0.4 m box on top of the first one (off centre), and a smooth-shaded UV sphere
(16 x 8, radius 0.5, a lightmap of 128 x 128 texels) hovering 0.1 m above the floor; a sun 40 degrees from the zenith and a
grey world. Each object has its own white Diffuse BSDF; the boxes and the sphere have a
`lightmap` UV map made by Smart UV Project before either bake, so both bakes use one layout.

photonlm: bpy.ops.photonlm.bake() to a 1 % target, all bounces.
Cycles:   DIFFUSE, pass_filter {'DIRECT', 'INDIRECT'} (irradiance / pi), 32 bounces, no
          clamping, CPU.
Metric per object: relative RMS error sqrt(mean((ours - cycles)^2)) / mean(cycles) over the
texels both bakes cover (all channels). Checks:
- the smooth sphere's error is at most 1.5 x that of the worst flat object (a faceted bake of
  the sphere is several times worse);
- faces pressed against another face (the lower box's bottom, the floor under it, the top
  box's bottom and the part of the lower box's top under it) are black in both bakes.
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402

RES = 32
BALL_RES = 128  # texels much smaller than the sphere's facets (0.2 m): a faceted bake shows them
CYCLES_SAMPLES = int(os.environ.get("PHOTONLM_TEST_CYCLES_SAMPLES", 2048))
RATIO_LIMIT = 1.5


def smart_uv(obj, margin):
    """A `lightmap` UV map made by Smart UV Project on the object's own mesh."""
    mesh = obj.data
    layer = mesh.uv_layers.new(name="lightmap")
    mesh.uv_layers.active = layer
    vl = bpy.context.view_layer
    for o in vl.objects:
        o.select_set(False)
    obj.select_set(True)
    vl.objects.active = obj
    bpy.ops.object.mode_set(mode='EDIT')
    bpy.ops.mesh.select_all(action='SELECT')
    bpy.ops.uv.smart_project(angle_limit=math.radians(66.0), island_margin=margin, area_weight=0.0,
                             correct_aspect=True, scale_to_bounds=False)
    bpy.ops.object.mode_set(mode='OBJECT')
    obj.select_set(False)


def mesh_object(name, op, material, res=RES, **kwargs):
    op(**kwargs)
    obj = bpy.context.active_object
    obj.name = name
    obj.data.name = name
    obj.data.materials.append(material)
    obj.photonlm.resolution = res
    smart_uv(obj, 2.0 / res)
    return obj


def build():
    scenes.clear_scene()
    objs = {}
    floor_mat = scenes.diffuse_material("floor", (0.8, 0.8, 0.8))
    objs["Floor"] = scenes.plane("Floor", floor_mat, size=4.0, resolution=RES)
    objs["Box"] = mesh_object("Box", bpy.ops.mesh.primitive_cube_add, scenes.diffuse_material("box", (0.8, 0.8, 0.8)),
                              size=0.6, location=(-0.8, -0.3, 0.3))
    objs["Top"] = mesh_object("Top", bpy.ops.mesh.primitive_cube_add, scenes.diffuse_material("top", (0.8, 0.8, 0.8)),
                              size=0.4, location=(-0.9, -0.4, 0.8))
    ball = mesh_object("Ball", bpy.ops.mesh.primitive_uv_sphere_add, scenes.diffuse_material("ball", (0.8, 0.8, 0.8)),
                       res=BALL_RES, segments=16, ring_count=8, radius=0.5, location=(0.7, 0.4, 0.6))
    ball.data.polygons.foreach_set("use_smooth", [True] * len(ball.data.polygons))
    ball.data.update()
    objs["Ball"] = ball
    scenes.add_light("sun", 'SUN', (0, 0, 5), rotation=(math.radians(40), 0, math.radians(30)), energy=3.0,
                     angle=math.radians(2))
    scenes.set_world_color((0.3, 0.3, 0.3))
    return objs


def main():
    scenes.setup_paths()
    checks = scenes.Checks("smooth_contact_vs_cycles")
    objs = build()
    names = list(objs)
    print("metric: relative RMS error against Cycles (%d samples, 32 bounces, no clamp) per object" % CYCLES_SAMPLES)
    ref, t_cycles = scenes.cycles_bake([objs[n] for n in names], None, {'DIRECT', 'INDIRECT'}, CYCLES_SAMPLES)
    last = scenes.photonlm_bake(50_000_000, 1024, seed=3, target_error=0.01)
    st = last["stats"]
    print("times: photonlm %.2f s (%d photons, error estimate %.2f %%); Cycles %.2f s"
          % (st["seconds_total"], st["photons_emitted"], 100 * st["error_estimate"], t_cycles))
    checks.check(not any("overlap" in w for w in last["warnings"]), "no overlapping lightmap UVs")
    errors = {}
    for name in names:
        ours = last["objects"][name]
        rgb, cov = ours["rgb"], ours["coverage"]
        written = ref[name].max(axis=2) > 0
        mask = (cov > 0) & (written | (rgb.max(axis=2) == 0))
        diff = rgb[mask] - ref[name][mask]
        errors[name] = float(np.sqrt(np.mean(diff ** 2)) / max(float(np.mean(ref[name][mask])), 1e-30))
        print("%-6s relative RMS error %.2f %% over %d texels (mean ours %.4f, Cycles %.4f)"
              % (name, 100 * errors[name], int(mask.sum()), float(np.mean(rgb[mask])),
                 float(np.mean(ref[name][mask]))))
    flat = max(errors[n] for n in names if n != "Ball")
    checks.check(errors["Ball"] <= RATIO_LIMIT * flat,
                 "smooth sphere %.2f %% <= %.1f x the worst flat object's %.2f %%"
                 % (100 * errors["Ball"], RATIO_LIMIT, 100 * flat))

    # Faces in contact: texels whose centre lies on a face pressed against another one.
    def texels_at(obj, test):
        """Covered texels of obj whose centre's world position satisfies test(p, n)."""
        mesh = obj.data
        mesh.calc_loop_triangles()
        m = np.array(obj.matrix_world)
        out = np.zeros((RES, RES), bool)
        uvl = mesh.uv_layers["lightmap"].data
        for lt in mesh.loop_triangles:
            uv = np.array([uvl[k].uv for k in lt.loops], np.float64) * RES
            p = np.array([(m @ np.append(mesh.vertices[v].co, 1.0))[:3] for v in lt.vertices])
            n = np.array(m[:3, :3] @ np.array(lt.normal))
            lo, hi = np.floor(uv.min(0)).astype(int), np.ceil(uv.max(0)).astype(int)
            for j in range(max(lo[1], 0), min(hi[1], RES)):
                for i in range(max(lo[0], 0), min(hi[0], RES)):
                    c = np.array([i + 0.5, j + 0.5])
                    e1, e2, d = uv[1] - uv[0], uv[2] - uv[0], c - uv[0]
                    det = e1[0] * e2[1] - e1[1] * e2[0]
                    if det == 0:
                        continue
                    b1 = (d[0] * e2[1] - d[1] * e2[0]) / det
                    b2 = (e1[0] * d[1] - e1[1] * d[0]) / det
                    # Well inside the triangle: a quarter texel from its edges in UV space.
                    if min(b1, b2, 1 - b1 - b2) * abs(det) / max(np.linalg.norm(e1), np.linalg.norm(e2), 1e-9) < 0.75:
                        continue
                    if test(p[0] + b1 * (p[1] - p[0]) + b2 * (p[2] - p[0]), n):
                        out[j, i] = True
        return out

    def inside(p, lo, hi):
        return all(lo[k] + 0.05 <= p[k] <= hi[k] - 0.05 for k in range(2))

    contact = {
        "Box": texels_at(objs["Box"], lambda p, n: (n[2] < -0.9) or
                         (n[2] > 0.9 and inside(p, (-1.1, -0.6), (-0.7, -0.2)))),
        "Top": texels_at(objs["Top"], lambda p, n: n[2] < -0.9),
        "Floor": texels_at(objs["Floor"], lambda p, n: inside(p, (-1.1, -0.6), (-0.5, 0.0))),
    }
    for name, mask in contact.items():
        ours = last["objects"][name]["rgb"][mask]
        cyc = ref[name][mask]
        checks.check(mask.sum() >= 4 and float(ours.max()) == 0.0,
                     "%-5s %d texels in contact are black (max %.3g; Cycles max %.3g)"
                     % (name, int(mask.sum()), float(ours.max()) if mask.any() else -1,
                        float(cyc.max()) if mask.any() else -1))
    checks.finish()


main()
