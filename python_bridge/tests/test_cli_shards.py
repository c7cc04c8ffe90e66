"""`photonlm bake --shard K/N` and `photonlm merge`: N shards merge into what one `photonlm bake` writes, bit for bit."""
import json
import os
import subprocess

import pytest

from test_cli import CLI, QUAD

pytestmark = pytest.mark.skipif(CLI is None or not os.access(CLI, os.X_OK),
                                reason="the photonlm CLI was not found (set PHOTONLM_LIBRARY)")

# A floor and a wall (bounce light between them: the final gather runs), 100 k photons: 25 batches.
WALL = {"positions": [-1, -1, 0, -1, 1, 0, -1, 1, 2, -1, -1, 2], "indices": [0, 1, 2, 0, 2, 3],
        "lightmap_uv": [0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1]}
SCENE = {
    "version": 1,
    "materials": [{"name": "grey", "albedo": 0.7}, {"name": "red", "albedo": [0.8, 0.2, 0.1]}],
    "meshes": [dict(QUAD, name="floor", material="grey", lightmap_resolution=16),
               dict(WALL, name="wall", material="red", lightmap_resolution=[8, 12])],
    "lights": [{"type": "POINT", "power": 200, "location": [0.2, 0.1, 1.2]}],
    "settings": {"photon_count": 100000, "direct_samples": 4, "seed": 3},
}


def cli(*args):
    return subprocess.run([CLI] + [str(a) for a in args], capture_output=True, text=True, timeout=300)


def outputs(folder):
    """Every file's bytes (folders skipped); report.json without what depends on the run (times, the scene path, threads)."""
    files = {}
    for name in sorted(os.listdir(folder)):
        if not (folder / name).is_file():
            continue
        data = (folder / name).read_bytes()
        if name == "report.json":
            report = json.loads(data)
            del report["times"], report["scene"], report["settings"]["thread_count"]
            data = json.dumps(report, sort_keys=True).encode()
        files[name] = data
    return files


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    folder = tmp_path_factory.mktemp("shards")
    path = folder / "scene.json"
    path.write_text(json.dumps(SCENE))
    r = cli("bake", path, "-o", folder / "single")
    assert r.returncode == 0, r.stderr
    return path, outputs(folder / "single")


@pytest.mark.parametrize("shards", [1, 2, 3, 4])
def test_merge_of_n_shards_is_the_single_bake(tmp_path, scene, shards):
    path, single = scene
    parts = tmp_path / "parts"
    for k in range(1, shards + 1):
        r = cli("bake", path, "--shard", "%d/%d" % (k, shards), "-o", parts, "--threads", k)
        assert r.returncode == 0, r.stderr
    assert sorted(os.listdir(parts)) == ["part-%05d-of-%05d.plmpart" % (k, shards) for k in range(1, shards + 1)]
    r = cli("merge", parts, "-o", tmp_path / "merged")
    assert r.returncode == 0, r.stderr
    merged = outputs(tmp_path / "merged")
    assert sorted(merged) == sorted(single) == ["floor_lightmap.exr", "report.json", "wall_lightmap.exr"]
    for name in single:
        assert merged[name] == single[name], name


def test_merge_refuses_a_missing_shard_and_writes_nothing(tmp_path, scene):
    path, _ = scene
    for k in (1, 3):
        assert cli("bake", path, "--shard", "%d/3" % k, "-o", tmp_path / "parts").returncode == 0
    r = cli("merge", tmp_path / "parts", "-o", tmp_path / "merged")
    assert r.returncode == 1, r.stderr
    assert "shard(s) 2 of 3 missing" in r.stderr, r.stderr
    assert not os.listdir(tmp_path / "merged")


def test_bad_shard_options(tmp_path, scene):
    path, _ = scene
    for bad in ("0/4", "5/4", "2", "a/b", "1/0"):
        r = cli("bake", path, "--shard", bad, "-o", tmp_path / "p")
        assert r.returncode == 1 and "--shard: '%s' is not K/N" % bad in r.stderr, r.stderr
    r = cli("bake", path, "--shard", "1/2", "--target-error", "0.05", "-o", tmp_path / "p")
    assert r.returncode == 1 and "cannot have a target error" in r.stderr, r.stderr
    assert cli("merge", "-o", tmp_path / "m").returncode == 1
    r = cli("merge", tmp_path / "nothing_here", "-o", tmp_path / "m")
    assert r.returncode == 1 and "no such part file or folder" in r.stderr, r.stderr


@pytest.mark.parametrize("ranges", [1, 3])
def test_texel_ranges_merge_into_the_single_bake(tmp_path, scene, ranges):
    """Photon shards, then the direct pass and the final gather by texel ranges, all in one folder."""
    path, single = scene
    parts = tmp_path / "parts"
    for k in (1, 2):
        assert cli("bake", path, "--shard", "%d/2" % k, "-o", parts).returncode == 0
    for k in range(1, ranges + 1):
        r = cli("bake", path, "--direct", "%d/%d" % (k, ranges), "-o", parts, "--threads", k)
        assert r.returncode == 0, r.stderr
    for k in range(1, ranges + 1):  # reads the folder it writes to: gather parts there are passed over
        r = cli("bake", path, "--gather", "%d/%d" % (k, ranges), "-o", parts)
        assert r.returncode == 0, r.stderr
    names = ["%s-%05d-of-%05d.plmpart" % (kind, k, ranges) for kind in ("direct", "gather") for k in range(1, ranges + 1)]
    assert sorted(os.listdir(parts)) == sorted(names + ["part-00001-of-00002.plmpart", "part-00002-of-00002.plmpart"])
    r = cli("merge", parts, "-o", tmp_path / "merged")
    assert r.returncode == 0, r.stderr
    merged = outputs(tmp_path / "merged")
    for name in single:
        assert merged[name] == single[name], name


def test_texel_range_options(tmp_path, scene):
    path, _ = scene
    r = cli("bake", path, "--direct", "3/2", "-o", tmp_path / "p")
    assert r.returncode == 1 and "--direct: '3/2' is not K/N" in r.stderr, r.stderr
    r = cli("bake", path, "--direct", "1/2", "--shard", "1/2", "-o", tmp_path / "p")
    assert r.returncode == 1 and "only one of --shard, --direct and --gather" in r.stderr, r.stderr
    r = cli("bake", path, "--direct", "1/2", "--parts", tmp_path, "-o", tmp_path / "p")
    assert r.returncode == 1 and "--parts is for --gather" in r.stderr, r.stderr
    assert cli("bake", path, "--direct", "1/2", "-o", tmp_path / "p").returncode == 0
    r = cli("bake", path, "--gather", "1/2", "-o", tmp_path / "p")  # no photon parts there
    assert r.returncode == 1 and "no photon parts" in r.stderr, r.stderr
    r = cli("merge", tmp_path / "p", "-o", tmp_path / "m")
    assert r.returncode == 1 and "no photon parts" in r.stderr, r.stderr
