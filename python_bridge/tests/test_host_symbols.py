"""The engine's calls reach its own libraries even when the host process loaded other definitions of
the same symbols first, as Debian's Blender 4.3 and 5.2 do with Embree 4 (whose rtcNewDevice,
rtcIntersect1 and rtcOccluded1 carry Embree 3's names).

A stand-in host: a small shared library that defines Embree's entry points as functions that do
nothing (a device that is NULL, rays that hit nothing), loaded with RTLD_GLOBAL before the bridge in
a fresh Python. Expected: the bridge's bake there equals the bake of a Python without that library,
bit for bit, with photons hitting the scene; loading the engine without RTLD_DEEPBIND
(PHOTONLM_DEEPBIND=0) in the same host does not bake it (which shows the stand-in does shadow
Embree).
"""
import os
import subprocess
import sys

FAKE_EMBREE = r"""
#include <stddef.h>
void* rtcNewDevice(const char* config) { (void)config; return NULL; }
void rtcIntersect1(void* scene, void* context, void* rayhit) { (void)scene; (void)context; (void)rayhit; }
void rtcOccluded1(void* scene, void* context, void* ray) { (void)scene; (void)context; (void)ray; }
"""

BAKE = r"""
import ctypes, os, sys
if len(sys.argv) > 1:
    ctypes.CDLL(sys.argv[1], mode=ctypes.RTLD_GLOBAL)
import numpy as np, photonlm
s = photonlm.Scene()
m = s.add_material((0.8, 0.8, 0.8))
uv = np.array([[[0, 0], [1, 0], [1, 1]], [[0, 0], [1, 1], [0, 1]]], np.float32)
s.add_mesh("floor", np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32),
           np.array([[0, 1, 2], [0, 2, 3]]), lightmap_uv=uv, resolution=8)
s.add_mesh("roof", np.array([[-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], np.float32),
           np.array([[0, 2, 1], [0, 3, 2]]), lightmap_uv=uv, resolution=8)
s.add_light("POINT", power=100.0, matrix=np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0.5], [0, 0, 0, 1]]))
r = s.bake(photons=20000, direct_samples=4, seed=3)
print("HITS", r.stats["photon_hits"])
print("RGB", r.lightmap(0).rgb.tobytes().hex() + r.lightmap(1).rgb.tobytes().hex())
"""


def bake(extra_env, *args, must_finish=True):
    env = dict(os.environ, **extra_env)
    r = subprocess.run([sys.executable, "-c", BAKE] + list(args), capture_output=True, text=True, env=env,
                       timeout=300)
    if r.returncode != 0 and not must_finish:
        return r.stderr.strip().splitlines()[-1]
    assert r.returncode == 0, r.stderr[-2000:]
    lines = dict(l.split(" ", 1) for l in r.stdout.splitlines() if " " in l)
    return int(lines["HITS"]), lines["RGB"]


def test_engine_binds_to_its_own_embree_inside_a_host_that_loaded_another(tmp_path):
    src = tmp_path / "fake_embree.c"
    src.write_text(FAKE_EMBREE)
    lib = tmp_path / "libfake_embree.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-o", str(lib), str(src)], check=True)

    hits, plain = bake({})
    assert hits > 0
    hosted_hits, hosted = bake({}, str(lib))
    assert hosted_hits == hits and hosted == plain
    # Bound to the stand-in, the engine fails to make its device (or, with another host, bakes
    # something else): the stand-in does shadow Embree's names.
    assert bake({"PHOTONLM_DEEPBIND": "0"}, str(lib), must_finish=False) != (hits, plain)
