"""`photonlm bake`: a scene file in, lightmap EXRs and report.json out; bad files exit 1 with the JSON path."""
import json
import os
import re
import shutil
import subprocess

import numpy as np
import pytest

import photonlm


def cli_path():
    lib = os.environ.get("PHOTONLM_LIBRARY")
    if not lib:
        return None
    return os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(lib)), "..", "bin", "photonlm"))


CLI = cli_path()
pytestmark = pytest.mark.skipif(
    CLI is None or not os.access(CLI, os.X_OK),
    reason="the photonlm CLI was not found: set PHOTONLM_LIBRARY to build/lib/libphotonlm.so, "
           "the CLI is expected at ../bin/photonlm next to it (looked at %s)" % CLI)

QUAD = {"positions": [-1, -1, 0, 1, -1, 0, 1, 1, 0, -1, 1, 0], "indices": [0, 1, 2, 0, 2, 3],
        "lightmap_uv": [0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1]}


def small_scene():
    """A fresh scene each call (tests edit it in place)."""
    return json.loads(json.dumps({
        "version": 1,
        "materials": [{"name": "grey", "albedo": 0.6}],
        "ol_groups": [{"name": "my props", "resolution": 4}],
        "meshes": [
            dict(QUAD, name="floor", material="grey", lightmap_resolution=8),
            # The same file name on a case-insensitive file system: numbered.
            dict(QUAD, name="Floor", material=0, lightmap_resolution=[4, 2]),
            {"name": "prop", "positions": [0, 0, 0.5, 0.2, 0, 0.5, 0, 0.2, 0.5], "indices": [0, 2, 1],
             "ol_group": "my props"},
        ],
        "lights": [{"type": "POINT", "power": 100, "location": [0, 0, 1]}],
        "settings": {"photon_count": 50000, "direct_samples": 4, "seed": 1},
    }))


def run_bake(tmp_path, scene, *args):
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    out = tmp_path / "out"
    r = subprocess.run([CLI, "bake", str(path), "-o", str(out)] + list(args), capture_output=True, text=True,
                       timeout=300)
    return r, out


def test_bake_writes_exrs_and_report(tmp_path):
    r, out = run_bake(tmp_path, small_scene(), "--photons", "20000", "--seed", "5", "--threads", "2")
    assert r.returncode == 0, r.stderr
    files = sorted(os.listdir(out))
    assert files == ["Floor_2_lightmap.exr", "floor_lightmap.exr", "my_props_ol.exr", "report.json"], files
    for f in files:
        assert (out / f).stat().st_size > 0
    report = json.loads((out / "report.json").read_text())
    # Command-line options override the file; the rest comes from the file.
    assert report["settings"]["photon_count"] == 20000
    assert report["settings"]["seed"] == 5
    assert report["settings"]["thread_count"] == 2
    assert report["settings"]["direct_samples"] == 4
    assert report["settings"]["texel_value"] == "CYCLES"
    assert report["settings"]["sampler"] == "DEFAULT"
    assert report["photons"]["emitted"] == 20000
    assert report["times"]["total"] > 0
    for key in ("error_estimate", "median", "p95"):
        assert report["stats"][key] >= 0
    assert isinstance(report["warnings"], list)
    meshes = {m["name"]: m for m in report["meshes"]}
    assert set(meshes) == {"floor", "Floor"}
    assert meshes["floor"]["file"] == "floor_lightmap.exr" and meshes["floor"]["size"] == [8, 8]
    assert meshes["Floor"]["file"] == "Floor_2_lightmap.exr" and meshes["Floor"]["size"] == [4, 2]
    # 100 W point light 1 m above the centre: irradiance / pi at the centre is 100 / (4 pi) / pi ~ 2.5.
    assert 0.3 < meshes["floor"]["mean_value"] < 3.0
    assert report["ol_groups"][0]["file"] == "my_props_ol.exr"
    assert report["ol_groups"][0]["resolution"] == 4
    # The quads cover their whole maps; texels above twice the RMS error estimate (no target), counted
    # as the add-on counts them (relative error = error / mean RGB), from the EXR.
    assert meshes["floor"]["texels"] == 64 and meshes["Floor"]["texels"] == 8
    for m in meshes.values():
        lm = photonlm.read_lightmap_exr(out / m["file"])
        value = lm.rgb.sum(axis=2, dtype=np.float32) / np.float32(3.0)
        relative = np.zeros_like(value)
        np.divide(lm.error, value, out=relative, where=value > 0)
        limit = np.float32(2.0 * report["stats"]["error_estimate"])
        assert m["texels_above_twice_target"] == int(np.count_nonzero(relative > limit)), m
    assert 0 < meshes["floor"]["texels_above_twice_target"] < 64  # 20,000 photons: some noisy texels, not all
    # Plain progress lines when stdout is not a terminal.
    assert "%" in r.stdout and "\r" not in r.stdout


@pytest.mark.skipif(shutil.which("iinfo") is None, reason="needs iinfo (Debian openimageio-tools)")
def test_exr_sizes_and_channels(tmp_path):
    r, out = run_bake(tmp_path, small_scene())
    assert r.returncode == 0, r.stderr
    info = subprocess.run(["iinfo", "-v", str(out / "Floor_2_lightmap.exr")], capture_output=True, text=True,
                          check=True).stdout
    assert re.search(r":\s+4 x\s+2, 5 channel", info) and "R, G, B, error, hits" in info, info
    info = subprocess.run(["iinfo", "-v", str(out / "my_props_ol.exr")], capture_output=True, text=True,
                          check=True).stdout
    assert re.search(r":\s+4 x\s+4, 6 channel", info) and "R, G, B, area, error, hits" in info, info


@pytest.mark.parametrize("edit, path, message", [
    (lambda s: s["meshes"][1]["positions"].__setitem__(7, "abc"), "scene.meshes[1].positions[7]",
     'expected a number, got "abc"'),
    (lambda s: s["lights"][0].__setitem__("type", "LASER"), "scene.lights[0].type",
     '"LASER" is not one of POINT, SPOT, SUN, AREA_RECT, AREA_DISK'),
    (lambda s: s["settings"].__setitem__("sampler", "HALTON"), "scene.settings.sampler", "is not one of"),
    (lambda s: s["meshes"][0].__setitem__("obj", "nowhere.obj"), "scene.meshes[0].positions",
     'not allowed together with "obj"'),
])
def test_malformed_file_exits_1_with_the_json_path(tmp_path, edit, path, message):
    scene = small_scene()
    edit(scene)
    r, out = run_bake(tmp_path, scene)
    assert r.returncode == 1, (r.returncode, r.stderr)
    assert path + ": " in r.stderr and message in r.stderr, r.stderr
    assert not out.exists() or not os.listdir(out)


def test_bad_options_and_missing_file_exit_1(tmp_path):
    r = subprocess.run([CLI, "bake", str(tmp_path / "nowhere.json"), "-o", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert r.returncode == 1 and "nowhere.json: cannot open" in r.stderr
    r, _ = run_bake(tmp_path, small_scene(), "--photons", "lots")
    assert r.returncode == 1 and "--photons" in r.stderr


def test_max_file_mb_raises_the_file_limit(tmp_path):
    # A 1.5 MiB scene file (spaces after the JSON): over a 1 MiB limit, under a 2 MiB one.
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(small_scene()) + " " * (3 << 19))
    out = tmp_path / "out"
    for command in (["bake", str(path), "-o", str(out)], ["gltf", str(path), str(out), "-o", str(tmp_path / "x.glb")]):
        r = subprocess.run([CLI] + command + ["--max-file-mb", "1"], capture_output=True, text=True, timeout=300)
        assert r.returncode == 1, r.stderr
        assert "larger than the limit of 1048576 bytes (1 MiB; --max-file-mb N raises it)" in r.stderr, r.stderr
    r = subprocess.run([CLI, "bake", str(path), "-o", str(out), "--max-file-mb", "2"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert (out / "report.json").exists()
    for bad in ("0", "-1", "lots"):
        r, _ = run_bake(tmp_path, small_scene(), "--max-file-mb", bad)
        assert r.returncode == 1 and "--max-file-mb: '%s' is not an integer" % bad in r.stderr, r.stderr


def test_interrupt_leaves_no_files(tmp_path):
    import signal
    import time
    scene = small_scene()
    scene["settings"] = {"photon_count": 0, "time_budget": 60, "target_error": 1e-9}
    path = tmp_path / "scene.json"
    path.write_text(json.dumps(scene))
    out = tmp_path / "out"
    p = subprocess.Popen([CLI, "bake", str(path), "-o", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True)
    p.stdout.readline()  # the first progress line: the bake (and the CLI's signal handler) has started
    time.sleep(0.5)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert os.listdir(out) == []


def test_demo_commands_create_the_output_folder(tmp_path):
    out = tmp_path / "new" / "folder"
    r = subprocess.run([CLI, "cornell", "--photons", "20000", "--res", "8", "-o", str(out)], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert len([f for f in os.listdir(out) if f.endswith("_lightmap.exr")]) == 7
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    r = subprocess.run([CLI, "furnace", "--photons", "1000", "-o", str(blocker / "x")], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 1
    assert "cannot create the output folder" in r.stderr and str(blocker) in r.stderr
