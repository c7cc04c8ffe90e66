"""The add-on zip is self-contained: installed from the zip, it loads and bakes without the build
folder and without Debian's Embree, TBB, OpenEXR or OpenSubdiv packages.

Expected:
- every shared library the zip's libphotonlm.so needs resolves inside the zip's lib/photonlm/
  folder or to the base system (glibc, libstdc++, libgcc_s, zlib), with LD_LIBRARY_PATH unset
  (scripts/bundle_libs.py --check);
- a Python without the build's library ($PHOTONLM_LIBRARY unset, the source tree off its path)
  loads the bridge from the unzipped add-on, bakes a lit plane, and its process maps Embree, TBB,
  OpenEXR and OpenSubdiv from the zip's folder, not from /usr/lib;
- a second Blender with the zip installed as a user add-on (BLENDER_USER_SCRIPTS, the add-on
  enabled by addon_utils like Preferences > Add-ons does) bakes a scene through the operator.
(Blender itself links Debian's TBB, Embree and OpenEXR, so inside Blender the loader may reuse
those already loaded copies of the same sonames; the first two checks show the zip does not need
them.)
"""
import os
import subprocess
import sys
import tempfile
import zipfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402

import bpy  # noqa: E402

SRC = os.environ.get("PHOTONLM_SOURCE_DIR") or os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BUNDLED = ("libembree3", "libtbb", "libOpenEXR", "libosdCPU")

PYTHON_BAKE = r"""
import numpy as np, photonlm
s = photonlm.Scene()
m = s.add_material((0.8, 0.8, 0.8))
uv = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)
s.add_mesh("floor", np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32),
           np.array([[0, 1, 2], [0, 2, 3]]), lightmap_uv=uv, resolution=8)
s.add_light("SUN", power=3.0)
r = s.bake(photons=10000, direct_samples=4)
print("BAKED", float(r.lightmap(0).rgb.mean()), photonlm.__file__)
print("MAPS", " ".join(sorted({l.split()[-1] for l in open("/proc/self/maps") if ".so" in l})))
"""

BLENDER_BAKE = r"""
import addon_utils, bpy, sys
addon_utils.enable("photonlm_blender", default_set=True, handle_error=lambda e: print("ENABLE ERROR", e))
from photonlm_blender import bake, bridge
for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.lights):
    for item in list(coll):
        coll.remove(item)
bpy.ops.mesh.primitive_plane_add(size=2.0)
light = bpy.data.lights.new("sun", 'SUN')
light.energy = 3.0
bpy.context.scene.collection.objects.link(bpy.data.objects.new("sun", light))
bpy.context.scene.photonlm.output_dir = sys.argv[-1]
bpy.context.scene.photonlm.photons = 20000
result = bpy.ops.photonlm.bake()
print("ZIPBAKE", result, sorted(bake.LAST.get("objects", {})), bridge.get().__file__)
"""


def main():
    checks = scenes.Checks("addon_zip")
    lib = os.environ.get("PHOTONLM_LIBRARY", "")
    archive = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(lib))), "photonlm_blender.zip")
    checks.check(os.path.isfile(archive), "the build made %s" % archive)
    root = tempfile.mkdtemp(prefix="photonlm-zip-")
    addons = os.path.join(root, "scripts", "addons")
    with zipfile.ZipFile(archive) as z:
        z.extractall(addons)
    for info in zipfile.ZipFile(archive).infolist():  # zipfile drops the executable bits
        mode = info.external_attr >> 16
        if mode:
            os.chmod(os.path.join(addons, info.filename), mode)
    folder = os.path.join(addons, "photonlm_blender", "lib", "photonlm")
    engine = os.path.join(folder, "libphotonlm.so")

    r = subprocess.run(["/usr/bin/python3",
                        os.path.join(SRC, "scripts", "bundle_libs.py"), "--check", engine],
                       capture_output=True, text=True)
    print(r.stdout, r.stderr)
    checks.check(r.returncode == 0, "every dependency of the zip's engine resolves inside the zip or to the "
                 "base system (bundle_libs.py --check exit %d)" % r.returncode)

    env = {k: v for k, v in os.environ.items()
           if k not in ("PHOTONLM_LIBRARY", "PYTHONPATH", "LD_LIBRARY_PATH", "PHOTONLM_SOURCE_DIR")}
    py = subprocess.run(["/usr/bin/python3", "-c", PYTHON_BAKE], capture_output=True, text=True, cwd=root,
                        env=dict(env, PYTHONPATH=os.path.join(addons, "photonlm_blender", "lib")))
    print(py.stdout[-2000:], py.stderr[-2000:])
    baked = [l for l in py.stdout.splitlines() if l.startswith("BAKED")]
    maps = next((l.split()[1:] for l in py.stdout.splitlines() if l.startswith("MAPS")), [])
    checks.check(py.returncode == 0 and baked and float(baked[0].split()[1]) > 0.0 and folder in baked[0],
                 "a Python without the build bakes with the zip's bridge and engine: %s" % (baked or py.returncode))
    for name in BUNDLED:
        paths = [m for m in maps if os.path.basename(m).startswith(name + ".") or os.path.basename(m).startswith(name + "-")]
        checks.check(paths and all(os.path.dirname(p) == folder for p in paths),
                     "%s is loaded from the zip: %s" % (name, paths))

    out = os.path.join(root, "lightmaps")
    bl = subprocess.run([bpy.app.binary_path, "-b", "--factory-startup", "--python-exit-code", "1",
                         "--python-expr", BLENDER_BAKE, "--", out], capture_output=True, text=True, cwd=root,
                        env=dict(env, BLENDER_USER_SCRIPTS=os.path.join(root, "scripts")))
    line = next((l for l in bl.stdout.splitlines() if l.startswith("ZIPBAKE")), "")
    print(bl.stdout[-3000:], bl.stderr[-2000:])
    checks.check(bl.returncode == 0 and "{'FINISHED'}" in line and "'Plane'" in line and folder in line,
                 "Blender with the zip installed as a user add-on bakes with it: %s" % (line or bl.returncode))
    checks.check(os.path.isfile(os.path.join(out, "Plane_lightmap.exr")), "and writes the lightmap")
    import shutil
    shutil.rmtree(root, ignore_errors=True)
    checks.finish()


main()
