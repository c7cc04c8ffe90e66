"""The add-on as a Blender extension (4.2 and later), installed as a user installs it, bakes with its
own engine libraries whatever this Blender loaded, and bakes what the CLI bakes.

1. `blender --command extension validate` accepts build/photonlm_blender_extension.zip.
2. `blender --command extension install-file -r user_default -e ZIP` installs and enables it into a
   fresh user folder (BLENDER_USER_RESOURCES), as Install from Disk does.
3. A Blender started on that user folder (no --factory-startup, so the extension loads) bakes
   Blender's default scene as it starts (the default cube with Blender's default material) on a
   floor under a sun, through the operator, with a fixed photon count and seed:
   - the engine is the extension's (the bridge's file lies in the installed extension) and the
     process maps libembree3, libOpenEXR and libosdCPU from the extension's lib/ folder;
   - photons hit the scene (stats photon_hits > 0; when the engine's Embree calls landed in the host's
     Embree 4, no photon hit anything) and the floor is lit (its mean texel > 0) with a shadow
     (the texels under the cube darker than the floor's mean);
   - File > Export > PhotonLM scene writes the same scene, `photonlm bake` bakes it outside Blender,
     and every lightmap equals the add-on's bit for bit (same float32 inputs, same seed: the engine's
     result depends on nothing else);
   - File > Export > glTF with PhotonLM lightmaps finds the add-on's hook as an extension
     (bl_ext.user_default.photonlm_blender) and gives the cube and the floor, which share Blender's
     default material, a copy of it each with its own lightmap (MOZ_lightmap).
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402

PHOTONS = 60_000
SEED = 5

CHILD = r"""
import bpy, json, os, sys
import numpy as np
args = json.loads(sys.argv[sys.argv.index("--") + 1])
report = {}
try:
    import addon_utils
    report["enabled"] = sorted(m.__name__ for m in addon_utils.modules() if addon_utils.check(m.__name__)[1]
                               and "photonlm" in m.__name__)
    scene = bpy.context.scene
    cube = bpy.data.objects.get("Cube")
    report["default_material"] = cube.active_material.name if cube and cube.active_material else None
    bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0.0, 0.0, -1.0))
    floor = bpy.context.active_object
    floor.name = "Floor"
    floor.data.materials.append(cube.active_material)
    for ob in list(scene.objects):
        if ob.type in ('LIGHT', 'CAMERA'):
            bpy.data.objects.remove(ob)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", 'SUN'))
    sun.data.energy = 3.0
    sun.rotation_euler = (0.3, 0.2, 0.0)
    scene.collection.objects.link(sun)
    props = scene.photonlm
    props.output_dir = args["out"]
    props.photons = args["photons"]
    props.seed = args["seed"]
    props.target_error = 0.0
    props.direct_samples = 4
    res = bpy.ops.photonlm.bake()
    record = sys.modules[[n for n in sys.modules if n.endswith("photonlm_blender.writeback.record")][0]]
    bridge = sys.modules[[n for n in sys.modules if n.endswith("photonlm_blender.bridge")][0]]
    report["result"] = sorted(res)
    report["version"] = list(sys.modules[report["enabled"][0]].VERSION)
    report["engine"] = bridge.get().__file__
    last = record.last()
    report["stats"] = {k: v for k, v in last.get("stats", {}).items() if isinstance(v, (int, float))}
    report["objects"] = sorted(last.get("objects", {}))
    report["maps"] = sorted({l.split()[-1] for l in open("/proc/self/maps") if ".so" in l})
    report["export"] = sorted(bpy.ops.photonlm.export_scene_file(filepath=args["scene_file"]))
    gltf_path = os.path.join(args["out"], "scene.glb")
    report["gltf"] = sorted(bpy.ops.photonlm.export_gltf(filepath=gltf_path))
    import struct
    data = open(gltf_path, "rb").read()
    doc = json.loads(data[20:20 + struct.unpack_from("<I", data, 12)[0]])
    report["gltf_lightmaps"] = sorted((m["extras"]["photonlm_lightmap"]["object"], m["name"])
                                      for m in doc.get("materials", []) if "MOZ_lightmap" in m.get("extensions", {}))
except Exception as e:
    import traceback
    report["error"] = traceback.format_exc()
with open(args["report"], "w") as f:
    json.dump(report, f)
"""


def run(cmd, env=None, timeout=600):
    print("$ " + " ".join(cmd), flush=True)
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env)
    print(r.stdout[-3000:], r.stderr[-3000:], flush=True)
    return r


def main():
    import numpy as np
    checks = scenes.Checks("extension")
    build = os.environ.get("PHOTONLM_BUILD_DIR") or os.path.join(
        os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "build")
    archive = os.path.join(build, "photonlm_blender_extension.zip")
    checks.check(bpy.app.version >= (4, 2, 0), "Blender %s has the extension system" % bpy.app.version_string)
    checks.check(os.path.isfile(archive), "the build made %s" % archive)
    blender = bpy.app.binary_path

    r = run([blender, "-b", "--factory-startup", "--command", "extension", "validate", archive])
    checks.check(r.returncode == 0, "extension validate accepts the extension (exit %d)" % r.returncode)

    home = tempfile.mkdtemp(prefix="photonlm-ext-")
    env = {k: v for k, v in os.environ.items()
           if k not in ("PHOTONLM_LIBRARY", "PYTHONPATH", "PHOTONLM_SOURCE_DIR")}
    env["BLENDER_USER_RESOURCES"] = home
    r = run([blender, "-b", "--command", "extension", "install-file", "-r", "user_default", "-e", archive], env=env)
    checks.check(r.returncode == 0, "extension install-file installs and enables it (exit %d)" % r.returncode)

    out = scenes.out_dir("extension")
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    args = dict(out=os.path.join(out, "addon"), photons=PHOTONS, seed=SEED, report=os.path.join(out, "report.json"),
                scene_file=os.path.join(out, "scene", "scene.json"))
    r = run([blender, "-b", "--python-exit-code", "1", "--python-expr", CHILD, "--", json.dumps(args)], env=env)
    rep = json.load(open(args["report"])) if os.path.isfile(args["report"]) else {"error": "no report"}
    print(json.dumps({k: v for k, v in rep.items() if k != "maps"}, indent=1))
    checks.check("error" not in rep and r.returncode == 0, "Blender with the extension installed baked: %s"
                 % rep.get("error", r.returncode))
    if "error" in rep:
        checks.finish()
    ext_dir = os.path.dirname(rep.get("engine", ""))
    checks.check(rep.get("enabled") and rep["enabled"][0].startswith("bl_ext."),
                 "the extension is enabled as %s" % rep.get("enabled"))
    import tomllib
    import zipfile
    with zipfile.ZipFile(archive) as z:
        manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
    checks.check(manifest.get("version") == ".".join(map(str, rep.get("version", []))),
                 "the manifest's version %s is the add-on's VERSION %s" % (manifest.get("version"), rep.get("version")))
    checks.check(rep.get("default_material") is not None, "the default cube has Blender's default material (%s)"
                 % rep.get("default_material"))
    checks.check(rep.get("result") == ["FINISHED"] and home in ext_dir,
                 "the operator finished with the extension's engine %s" % rep.get("engine"))
    for name in ("libembree3.so", "libosdCPU.so.3.5", "libphotonlm.so"):
        paths = [m for m in rep["maps"] if os.path.basename(m).startswith(name)]
        checks.check(paths and all(os.path.dirname(p) == ext_dir for p in paths),
                     "%s is mapped from the extension's folder: %s" % (name, paths))
    # Every bundled soname is in the process once: the extension's copy, or the host's where the
    # host loaded that soname first (Debian 13's Blender: libOpenEXR-3_1.so.30, libtbb.so.12).
    for soname in sorted(n for n in os.listdir(ext_dir) if ".so." in n):
        paths = [m for m in rep["maps"] if os.path.basename(m).startswith(soname)]
        checks.check(len(paths) == 1, "one copy of %s in the process: %s" % (soname, paths))
    print("this Blender's own Embree, OpenEXR and OpenSubdiv in the process: %s"
          % [m for m in rep["maps"] if os.path.dirname(m) != ext_dir and ("embree" in m or "OpenEXR" in m or "osd" in m)])
    stats = rep.get("stats", {})
    checks.check(stats.get("photon_hits", 0) > 0, "photons hit the scene: %s hits" % stats.get("photon_hits"))

    floor = scenes.exr_rgb(os.path.join(args["out"], "Floor_lightmap.exr"))
    h, w, _ = floor.shape
    centre = floor[h * 3 // 8:h * 5 // 8, w * 3 // 8:w * 5 // 8].mean()
    checks.check(floor.mean() > 0.0 and centre < 0.8 * floor.mean(),
                 "the floor is lit (mean %.4g) with the cube's shadow under it (%.4g)" % (floor.mean(), centre))

    checks.check(rep.get("export") == ["FINISHED"] and os.path.isfile(args["scene_file"]),
                 "the scene file was exported")
    lightmapped = rep.get("gltf_lightmaps", [])
    checks.check(rep.get("gltf") == ["FINISHED"] and [o for o, _ in lightmapped] == sorted(rep.get("objects", []))
                 and len({m for _, m in lightmapped}) == 1,
                 "File > Export > glTF with PhotonLM lightmaps, as the exporter finds the extension's hook: a "
                 "material copy with MOZ_lightmap per baked object, sharing Blender's material: %s" % lightmapped)
    cli = scenes.cli_path()
    cli_out = os.path.join(out, "cli")
    r = run([cli, "bake", args["scene_file"], "-o", cli_out])
    checks.check(r.returncode == 0, "photonlm bake baked the exported file (exit %d)" % r.returncode)
    with open(args["scene_file"]) as f:
        files = {o["object"]: o["lightmap_file"] for o in json.load(f).get("metadata", {}).get("objects", [])}
    checks.check(sorted(files) == rep.get("objects"), "the file names each baked object's lightmap: %s" % files)
    for name in rep.get("objects", []):
        ours = scenes.exr_rgb(os.path.join(args["out"], name + "_lightmap.exr"))
        theirs_path = os.path.join(cli_out, files.get(name, "?"))
        theirs = scenes.exr_rgb(theirs_path) if os.path.isfile(theirs_path) else None
        same = theirs is not None and theirs.shape == ours.shape and np.array_equal(theirs, ours)
        diff = float(np.max(np.abs(theirs - ours))) if theirs is not None and theirs.shape == ours.shape else -1
        checks.check(same, "%s: the add-on's lightmap equals the CLI's bit for bit (max |diff| %.3g)" % (name, diff))
    shutil.rmtree(home, ignore_errors=True)
    checks.finish()


main()
