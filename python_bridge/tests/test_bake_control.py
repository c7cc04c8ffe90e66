"""Progress, cancel, determinism and EXR output."""
import os
import re
import shutil
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import photonlm
from scenes import QUAD_TRIANGLES, QUAD_UV, box_faces, plane, translation


def box_scene(scene, rho=0.8, res=8):
    scene.add_material(albedo=rho)
    scene.add_material(albedo=rho, emission=1.0)
    meshes = []
    for i, quad in enumerate(box_faces()):
        meshes.append(scene.add_mesh("face%d" % i, quad, QUAD_TRIANGLES, QUAD_UV,
                                     material_ids=[int(i == 5)] * 2, resolution=res))
    scene.add_light("POINT", power=50.0, matrix=translation(0.3, 0.4, 0.5))
    return meshes


def test_cancel_is_prompt_and_scene_stays_usable():
    calls = []
    cancel_at = []

    def progress(fraction, stage):
        calls.append((time.perf_counter(), fraction, stage))
        if calls[-1][0] - calls[0][0] > 0.3:
            cancel_at.append(time.perf_counter())
            return False
        return True

    with photonlm.Scene() as scene:
        meshes = box_scene(scene, rho=0.95)
        t0 = time.perf_counter()
        with pytest.raises(photonlm.BakeCancelled) as e:
            scene.bake(photons=1_000_000_000, progress=progress)
        t1 = time.perf_counter()
        assert e.value.status == "PLM_ERROR_CANCELLED"
        assert cancel_at, "the progress callback was never asked twice in %.2f s (%d calls)" % (t1 - t0, len(calls))
        assert t1 - cancel_at[0] < 0.5, "bake returned %.2f s after cancel" % (t1 - cancel_at[0])
        assert len(cancel_at) == 1, "callback still called after cancelling"
        gaps = np.diff([c[0] for c in calls])
        assert gaps.max() < 0.5, "progress callback silent for %.2f s" % gaps.max()
        assert all(0 <= c[1] <= 1 and isinstance(c[2], str) and c[2] for c in calls), calls
        with scene.bake(photons=20_000) as result:  # the scene still bakes
            assert result.lightmap(meshes[0]).hits.sum() > 0


def test_progress_reaches_the_end():
    fractions = []
    with photonlm.Scene() as scene:
        box_scene(scene)
        with scene.bake(photons=300_000, progress=lambda f, s: fractions.append(f)):
            pass
    # Non-decreasing up to rounding (0.05 + 0.9 * 1 is a hair above 0.95), ending at 1.
    assert fractions and np.all(np.diff(fractions) >= -1e-12) and 0 <= fractions[0], fractions
    assert fractions[-1] == 1.0, fractions


class Boom(Exception):
    pass


@pytest.mark.parametrize("exception", [Boom, KeyboardInterrupt])
def test_exception_in_progress_is_reraised(exception):
    calls = []

    def progress(fraction, stage):
        calls.append(fraction)
        raise exception("from the callback")

    with photonlm.Scene() as scene:
        box_scene(scene)
        t0 = time.perf_counter()
        with pytest.raises(exception, match="from the callback"):
            scene.bake(photons=1_000_000_000, progress=progress)
        assert time.perf_counter() - t0 < 2.0
        assert len(calls) == 1


def test_bake_releases_the_gil():
    """While a worker thread bakes, the main thread keeps running Python (Blender's UI stays alive).
    The switch interval is raised so that a thread holding the GIL is never preempted: the main
    thread then advances between the bake's first and last progress call only if the C call
    released the GIL."""
    ticks = [0]
    seen = []
    done = threading.Event()

    def progress(fraction, stage):
        seen.append(ticks[0])

    with photonlm.Scene() as scene:
        box_scene(scene, rho=0.8)
        worker = threading.Thread(target=lambda: (scene.bake(photons=400_000, threads=1, progress=progress).close(),
                                                 done.set()))
        old = sys.getswitchinterval()
        sys.setswitchinterval(5.0)
        try:
            worker.start()
            while not done.is_set():
                ticks[0] += 1
                if ticks[0] % 100 == 0:
                    time.sleep(0)  # lets the worker take the GIL for its progress calls
            worker.join()
        finally:
            sys.setswitchinterval(old)
    assert len(seen) >= 2 and seen[-1] - seen[0] > 1000, seen


def test_same_seed_same_result_any_thread_count():
    def bake(seed, threads):
        with photonlm.Scene() as scene:
            meshes = box_scene(scene)
            with scene.bake(photons=100_000, seed=seed, threads=threads) as result:
                return [result.lightmap(m) for m in meshes]

    a, b, c, d = bake(7, 2), bake(7, 2), bake(7, 1), bake(8, 2)
    for la, lb, lc, ld in zip(a, b, c, d):
        for field in photonlm.Lightmap._fields:
            assert np.array_equal(getattr(la, field), getattr(lb, field)), field
            assert np.array_equal(getattr(la, field), getattr(lc, field)), "threads 1 vs 2: " + field
    assert not np.array_equal(a[0].rgb, d[0].rgb), "seed has no effect"


def test_write_exr(tmp_path):
    width, height = 6, 4
    with photonlm.Scene() as scene:
        scene.add_material(albedo=0.0)
        pos, tri, uv = plane(1.0)
        mesh = scene.add_mesh("floor", pos, tri, uv, resolution=(width, height))
        scene.add_light("POINT", power=300.0, matrix=translation(-0.5, 0.7, 0.5))
        with scene.bake(photons=50_000) as result:
            lm = result.lightmap(mesh)
            out = tmp_path / "floor.exr"
            result.write_exr(mesh, out)            # os.PathLike
            result.write_exr(mesh, str(tmp_path / "again.exr"))
            with pytest.raises(photonlm.PhotonlmError) as e:
                result.write_exr(mesh, tmp_path / "no" / "such" / "dir.exr")
            assert e.value.status == "PLM_ERROR_IO" and e.value.message
    assert sorted(os.listdir(tmp_path)) == ["again.exr", "floor.exr"]  # no temporaries left
    assert out.read_bytes()[:4] == bytes([0x76, 0x2F, 0x31, 0x01])
    if shutil.which("oiiotool") is None:
        pytest.skip("oiiotool not installed")
    info = subprocess.run(["oiiotool", "--info", "-v", str(out)], check=True, capture_output=True, text=True).stdout
    assert "%d x %4d" % (width, height) in info or re.search(r"\b%d x\s+%d\b" % (width, height), info), info
    channels = re.search(r"channel list: (.*)", info).group(1).replace(" ", "").split(",")
    assert channels == ["R", "G", "B", "error", "hits"], channels
    dump = subprocess.run(["oiiotool", "--dumpdata", str(out)], check=True, capture_output=True, text=True).stdout
    pixels = np.zeros((height, width, 5))
    for x, y, values in re.findall(r"Pixel \((\d+), (\d+)\): (.*)", dump):
        pixels[int(y), int(x)] = [float(v) for v in values.split()]
    expected = np.concatenate([lm.rgb, lm.error[..., None], lm.hits[..., None]], axis=2)[::-1]  # file: top row first
    assert np.allclose(pixels, expected, rtol=1e-3, atol=1e-6)
