"""Orientation lightmaps through the add-on: per object, automatic, per collection.

Scene: the Cornell box with a UV sphere (r = 0.3 m) floating in it, a dense ico sphere on a tiny
lightmap, and a collection 'props' of two cubes marked 'One Orientation Lightmap' (one of them
without a lightmap of its own).

Expected:
- The sphere baked with Lighting = Orientation Lightmap matches the same sphere baked with an
  ordinary lightmap (the limit case where an OL equals a lightmap: every normal occurs once on a
  sphere; the lightmap as texel averages, like the OL): coverage-weighted means within 4 %
  (measured 2.5 %, systematic: not explained yet; the bilinear lookup across the equal-area
  map's seams is the suspect), texel values within 12 % mean absolute deviation (photon noise
  of both bakes plus the OL's 16 x 16 bins; measured 7.6 %).
- The report names each OL and why; AUTO turns the dense sphere (more than 4 triangles per
  texel) into an OL; the collection gets one OL listing both cubes; OL EXRs are written.
- The resolved lightmap images exist, are finite and non-zero.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402


def add_sphere(name, location, radius, kind='UV', res=32, subdivisions=3):
    if kind == 'UV':
        bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, location=location, segments=32, ring_count=16)
    else:
        bpy.ops.mesh.primitive_ico_sphere_add(radius=radius, location=location, subdivisions=subdivisions)
    obj = bpy.context.active_object
    obj.name = name
    obj.data.materials.append(scenes.diffuse_material("mat_" + name, (0.7, 0.7, 0.7)))
    obj.photonlm.resolution = res
    return obj


def add_cube(name, location, size, collection):
    bpy.ops.mesh.primitive_cube_add(size=size, location=location)
    obj = bpy.context.active_object
    obj.name = name
    obj.data.materials.append(scenes.diffuse_material("mat_" + name, (0.6, 0.6, 0.6)))
    obj.photonlm.resolution = 16
    for c in list(obj.users_collection):
        c.objects.unlink(obj)
    collection.objects.link(obj)
    return obj


def sphere_map(last, name):
    info = last["objects"][name]
    return np.asarray(info["rgb"], np.float64), np.asarray(info["coverage"], np.float64)


def main():
    checks = scenes.Checks("orientation_lightmaps")
    scenes.setup_paths()
    scenes.clear_scene()
    scenes.cornell_box(resolution=16)
    sphere = add_sphere("ball", (0.0, -0.2, 1.2), 0.3)
    dense = add_sphere("dense", (0.5, 0.5, 0.3), 0.15, kind='ICO', res=4, subdivisions=3)  # 1280 triangles
    props = bpy.data.collections.new("props")
    bpy.context.scene.collection.children.link(props)
    props.photonlm.orientation_lightmap = True
    cube_a = add_cube("prop_a", (-0.5, -0.5, 0.15), 0.3, props)
    cube_b = add_cube("prop_b", (-0.6, 0.0, 0.1), 0.2, props)
    cube_b.photonlm.enabled = False  # geometry only: its light still goes into the collection's OL
    bpy.context.scene.photonlm.output_dir = scenes.out_dir("ol")

    sphere.photonlm.mode = 'LIGHTMAP'
    ref = scenes.photonlm_bake(4_000_000, 64, seed=3, target_error=0.0, texel_value="AREA")
    ref_rgb, ref_cov = sphere_map(ref, "ball")
    checks.check("ball" not in ref.get("ols", {}), "Lighting = Lightmap: the sphere has no OL")

    sphere.photonlm.mode = 'ORIENTATION'
    last = scenes.photonlm_bake(4_000_000, 64, seed=4, target_error=0.0)
    rgb, cov = sphere_map(last, "ball")
    ols = last.get("ols", {})
    reports = [t for _level, t in last["reports"]]
    checks.check("ball" in ols and "Orientation Lightmap" in ols["ball"]["reason"],
                  "Lighting = Orientation Lightmap: the sphere gets its own OL (%s)" % ols.get("ball"))
    m_ol = scenes.coverage_weighted_mean(rgb, cov)
    m_lm = scenes.coverage_weighted_mean(ref_rgb, ref_cov)
    rel = float(np.abs(m_ol - m_lm).max() / m_lm.max())
    checks.check(rel < 0.04, "sphere mean: OL %s vs lightmap %s (%.2f %%, limit 4 %%)"
                 % (np.round(m_ol, 4), np.round(m_lm, 4), 100 * rel))
    mask = (cov > 0.99) & (ref_cov > 0.99)
    dev = float(np.abs(rgb[mask] - ref_rgb[mask]).mean() / ref_rgb[mask].mean())
    checks.check(dev < 0.12, "sphere texels: OL vs lightmap mean absolute deviation %.1f %% over %d texels "
                 "(limit 12 %%)" % (100 * dev, int(mask.sum())))
    checks.check(bool(np.all(np.isfinite(rgb))) and rgb[mask].min() > 0.0, "resolved sphere lightmap finite, > 0")

    checks.check("dense" in ols and ols["dense"]["reason"].startswith("Auto:"),
                 "AUTO: the dense sphere (1280 triangles on 16 texels) gets an OL: %s" % ols.get("dense"))
    checks.check(any("orientation lightmap" in t and "dense" in t for t in reports),
                 "the report names the automatic OL")
    coll = ols.get("collection_props")
    checks.check(coll is not None and sorted(coll["objects"]) == ["prop_a", "prop_b"],
                 "collection 'props': one OL over both cubes (%s)" % coll)
    a_rgb, a_cov = sphere_map(last, "prop_a")
    checks.check(scenes.coverage_weighted_mean(a_rgb, a_cov).max() > 0.0, "prop_a's resolved lightmap is lit")
    checks.check("prop_b" not in last["objects"], "prop_b (no lightmap of its own) gets no image")
    for name, info in ols.items():
        checks.check(os.path.isfile(info["path"]) and info["hits"] > 0,
                     "OL '%s': %s written, %d hits" % (name, os.path.basename(info["path"]), info["hits"]))
    checks.check(bpy.data.images.get("ball_lightmap") is not None, "image 'ball_lightmap' exists")

    # Lightmap + OL Backup: the sphere keeps its lightmap; noisy texels lean on its OL.
    sphere.photonlm.mode = 'BACKUP'
    backed = scenes.photonlm_bake(4_000_000, 64, seed=5, target_error=0.0)
    b_rgb, b_cov = sphere_map(backed, "ball")
    m_b = scenes.coverage_weighted_mean(b_rgb, b_cov)
    rel_b = float(np.abs(m_b - m_lm).max() / m_lm.max())
    checks.check("ball" in backed.get("ols", {}) and "Backup" in backed["ols"]["ball"]["reason"] and rel_b < 0.03,
                 "Lightmap + OL Backup: an OL beside the lightmap, mean %s vs %s (%.2f %%, limit 3 %%)"
                 % (np.round(m_b, 4), np.round(m_lm, 4), 100 * rel_b))

    # prop_b has no lightmap: its material looks the collection's OL up by the world normal.
    tree = bpy.data.materials["mat_prop_b"].node_tree
    group_nodes = [n for n in tree.nodes if n.bl_idname == 'ShaderNodeGroup' and n.node_tree is not None
                   and n.node_tree.name == "PhotonLM OL Lookup"]
    images = [n.image.name for n in tree.nodes if n.bl_idname == 'ShaderNodeTexImage' and n.image]
    checks.check(len(group_nodes) == 1 and "collection_props_ol" in images,
                 "prop_b's material looks up the collection OL by normal (images %s)" % images)
    if group_nodes:
        worst = check_lookup_group(group_nodes[0].node_tree)
        checks.check(worst < 1e-5, "the node group maps normals as the engine's equal-area octahedral map "
                     "(worst |uv difference| %.2g over 2000 normals)" % worst)
    checks.finish()


def oct_encode(d):
    """The engine's mapping (native/src/ol/octahedral.h)."""
    ax, ay, az = abs(d[0]), abs(d[1]), abs(d[2])
    r = np.sqrt((ax * ax + ay * ay) / (1.0 + az))
    phi = np.arctan2(ay, ax) * 2.0 / np.pi
    b = phi * r
    a = r - b
    if d[2] < 0:
        a, b = 1.0 - b, 1.0 - a
    return 0.5 * (np.copysign(a, d[0]) + 1.0), 0.5 * (np.copysign(b, d[1]) + 1.0)


def check_lookup_group(group):
    """Evaluate the group's math nodes in Python for random normals against oct_encode."""
    ops = {'ABSOLUTE': lambda a, b, c: abs(a), 'SQRT': lambda a, b, c: np.sqrt(max(a, 0.0)),
           'MAXIMUM': lambda a, b, c: max(a, b), 'MINIMUM': lambda a, b, c: min(a, b),
           'SUBTRACT': lambda a, b, c: a - b, 'ADD': lambda a, b, c: a + b, 'MULTIPLY': lambda a, b, c: a * b,
           'DIVIDE': lambda a, b, c: a / b if b != 0 else 0.0, 'ARCTANGENT': lambda a, b, c: np.arctan(a),
           'LESS_THAN': lambda a, b, c: float(a < b), 'GREATER_THAN': lambda a, b, c: float(a > b),
           'MULTIPLY_ADD': lambda a, b, c: a * b + c}
    rng = np.random.default_rng(5)
    worst = 0.0
    for _ in range(2000):
        n = rng.normal(size=3)
        n /= np.linalg.norm(n)
        cache = {}

        def value(socket):
            if socket.is_linked:
                return out_value(socket.links[0].from_socket)
            v = socket.default_value
            return v if isinstance(v, float) else tuple(v)

        def out_value(sock):
            node = sock.node
            key = (node.name, sock.identifier)
            if key in cache:
                return cache[key]
            if node.bl_idname == 'ShaderNodeNewGeometry':
                res = tuple(n)
            elif node.bl_idname == 'ShaderNodeSeparateXYZ':
                vec = value(node.inputs[0])
                res = vec["XYZ".index(sock.name)]
            elif node.bl_idname == 'ShaderNodeMath':
                res = ops[node.operation](*[value(node.inputs[i]) for i in range(3)])
            elif node.bl_idname == 'ShaderNodeCombineXYZ':
                res = tuple(value(i) for i in node.inputs)
            else:
                raise ValueError(node.bl_idname)
            cache[key] = res
            return res
        out = next(nd for nd in group.nodes if nd.bl_idname == 'NodeGroupOutput')
        uv = value(out.inputs[0])
        u, v = oct_encode(n)
        worst = max(worst, abs(uv[0] - u), abs(uv[1] - v))
    return worst


main()
