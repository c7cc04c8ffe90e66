"""Sharded bakes on one machine against one process: shard and merge times, part file sizes.

    /usr/bin/python3 docs/bench_shards.py [--photonlm build/bin/photonlm] [--res 128] [--photons 16000000]
                                          [--shards 1 2 4 8] [--threads 2]
    /usr/bin/python3 docs/bench_shards.py --ranges 1 2 4 8 [--objects 32] [--photons 2000000] [--threads 2]

A closed room (floor, ceiling, four walls, a box; 11 faces of res x res texels) lit by a point light
under the ceiling. Bakes it once (`photonlm bake`), then for each shard count N runs the N shards
one after the other (`photonlm bake --shard K/N`, as N machines would run them at once) and the
merge (`photonlm merge`), checks the merge's EXRs against the single bake byte for byte, and prints
per N, in CPU seconds (user + system): the slowest shard, the sum over shards, the merge, the part files' total size and a part's
size per million texels, and the overhead of the sharded bake over the single one
((sum of shards + merge) / single - 1: each shard repeats the set-up, the merge reads the parts).

With --ranges: the open sunlit courtyard of docs/bench_open_courtyard.py (--objects spheres of 16
rings, 64 x 64 texels each, a ground and four walls), where the direct pass and the final gather are
most of the bake. Bakes it once, then 2 photon shards and, per range count M, the M direct ranges
(`--direct K/M`) and the M gather ranges (`--gather K/M`) one after the other and the merge; prints
the slowest and summed direct and gather tasks, the merge, the direct and gather parts' sizes, the
overhead ((all tasks + merge) / single - 1) and whether the merge equals the single bake.
"""
import argparse
import json
import os
import resource
import shutil
import subprocess
import tempfile


def quad(name, origin, eu, ev, res, material):
    o, u, v = origin, eu, ev
    pts = [o, [o[i] + u[i] for i in range(3)], [o[i] + u[i] + v[i] for i in range(3)], [o[i] + v[i] for i in range(3)]]
    return {"name": name, "material": material, "lightmap_resolution": res,
            "positions": [c for p in pts for c in p], "indices": [0, 1, 2, 0, 2, 3],
            "lightmap_uv": [0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1]}


def room(res, photons):
    """A 4 x 4 x 3 m room, faces inward, and a 1 x 1 x 1 m box on the floor (5 faces)."""
    w, h = 4.0, 3.0
    meshes = [
        quad("floor", [0, 0, 0], [w, 0, 0], [0, w, 0], res, "white"),
        quad("ceiling", [0, 0, h], [0, w, 0], [w, 0, 0], res, "white"),
        quad("wall_x0", [0, 0, 0], [0, w, 0], [0, 0, h], res, "red"),
        quad("wall_x1", [w, 0, 0], [0, 0, h], [0, w, 0], res, "green"),
        quad("wall_y0", [0, 0, 0], [0, 0, h], [w, 0, 0], res, "white"),
        quad("wall_y1", [0, w, 0], [w, 0, 0], [0, 0, h], res, "white"),
    ]
    b0, s = [1.5, 1.5, 0.0], 1.0
    meshes += [
        quad("box_top", [b0[0], b0[1], s], [s, 0, 0], [0, s, 0], res, "white"),
        quad("box_x0", [b0[0], b0[1], 0], [0, 0, s], [0, s, 0], res, "white"),
        quad("box_x1", [b0[0] + s, b0[1], 0], [0, s, 0], [0, 0, s], res, "white"),
        quad("box_y0", [b0[0], b0[1], 0], [s, 0, 0], [0, 0, s], res, "white"),
        quad("box_y1", [b0[0], b0[1] + s, 0], [0, 0, s], [s, 0, 0], res, "white"),
    ]
    return {"version": 1,
            "materials": [{"name": "white", "albedo": 0.75}, {"name": "red", "albedo": [0.7, 0.1, 0.1]},
                          {"name": "green", "albedo": [0.1, 0.6, 0.1]}],
            "meshes": meshes,
            "lights": [{"type": "POINT", "power": 800, "location": [2.0, 2.6, 2.7]}],
            "settings": {"photon_count": photons, "direct_samples": 16, "seed": 1}}


def run(cmd):
    """CPU seconds (user + system) of the command: on a shared machine wall times say little."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = subprocess.run(cmd, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        raise SystemExit("%s failed: %s" % (" ".join(cmd), r.stderr))
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), r.stdout


def texel_ranges(a, tmp):
    import sys
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import bench_open_courtyard
    folder = os.path.join(tmp, "court")
    bench_open_courtyard.build(folder, a.objects, 16, False, {"photon_count": a.photons, "seed": 1})
    scene = os.path.join(folder, "scene.json")
    threads = ["--threads", str(a.threads)]
    single_dir = os.path.join(tmp, "single")
    t_single, _ = run([a.photonlm, "bake", scene, "-o", single_dir] + threads)
    rep = json.load(open(os.path.join(single_dir, "report.json")))
    times = rep["times"]
    print("open courtyard: %d objects, %d photons, %d threads, %d direct samples"
          % (a.objects, a.photons, a.threads, rep["direct_samples"]))
    print("single bake: %.2f CPU s (wall: set-up %.2f, direct %.2f, photons+gather %.2f, total %.2f)"
          % (t_single, times["setup"], times["direct"], times["trace"], times["total"]))
    photon_dir = os.path.join(tmp, "photons")
    t_photons = sum(run([a.photonlm, "bake", scene, "--shard", "%d/2" % k, "-o", photon_dir] + threads)[0]
                    for k in (1, 2))
    t_setup, _ = run([a.photonlm, "bake", scene, "--shard", "1/100000", "-o", os.path.join(tmp, "empty")] + threads)
    t_merge0, _ = run([a.photonlm, "merge", photon_dir, "-o", os.path.join(tmp, "merged0")] + threads)
    print("2 photon shards: %.2f CPU s in all; a set-up alone %.2f CPU s; their merge alone (direct pass and "
          "gather on the merging machine) %.2f CPU s" % (t_photons, t_setup, t_merge0))
    print("CPU seconds:")
    print("%6s %10s %10s %10s %10s %8s %12s %12s %9s %s" % ("ranges", "max direct", "sum direct", "max gather",
                                                           "sum gather", "merge", "direct (MB)", "gather (MB)",
                                                           "overhead", "identical"))
    for m in a.ranges:
        parts = os.path.join(tmp, "parts%d" % m)
        shutil.copytree(photon_dir, parts)
        direct = [run([a.photonlm, "bake", scene, "--direct", "%d/%d" % (k, m), "-o", parts] + threads)[0]
                  for k in range(1, m + 1)]
        gather = [run([a.photonlm, "bake", scene, "--gather", "%d/%d" % (k, m), "-o", parts] + threads)[0]
                  for k in range(1, m + 1)]
        size = {kind: sum(os.path.getsize(os.path.join(parts, p)) for p in os.listdir(parts) if p.startswith(kind))
                for kind in ("direct", "gather")}
        merged = os.path.join(tmp, "merged%d" % m)
        t_merge, _ = run([a.photonlm, "merge", parts, "-o", merged] + threads)
        same = all(open(os.path.join(single_dir, f), "rb").read() == open(os.path.join(merged, f), "rb").read()
                   for f in os.listdir(single_dir) if f.endswith(".exr"))
        overhead = (t_photons + sum(direct) + sum(gather) + t_merge) / t_single - 1.0
        print("%6d %10.2f %10.2f %10.2f %10.2f %8.2f %12.2f %12.2f %8.1f%% %s"
              % (m, max(direct), sum(direct), max(gather), sum(gather), t_merge, size["direct"] / 1e6,
                 size["gather"] / 1e6, 100 * overhead, "yes" if same else "NO"))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--photonlm", default=os.path.join(os.path.dirname(__file__), "..", "build", "bin", "photonlm"))
    ap.add_argument("--res", type=int, default=128)
    ap.add_argument("--photons", type=int, default=16000000)
    ap.add_argument("--shards", type=int, nargs="+", default=[1, 2, 4, 8])
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--ranges", type=int, nargs="*", help="texel range counts (the open courtyard)")
    ap.add_argument("--objects", type=int, default=32)
    a = ap.parse_args()
    tmp = tempfile.mkdtemp(prefix="plm_bench_shards_")
    if a.ranges:
        try:
            texel_ranges(a, tmp)
        finally:
            shutil.rmtree(tmp)
        return
    try:
        scene = os.path.join(tmp, "room.json")
        with open(scene, "w") as f:
            json.dump(room(a.res, a.photons), f)
        texels = 11 * a.res * a.res
        single_dir = os.path.join(tmp, "single")
        t_single, _ = run([a.photonlm, "bake", scene, "-o", single_dir, "--threads", str(a.threads)])
        rep = json.load(open(os.path.join(single_dir, "report.json")))
        times = rep["times"]
        print("room: %d texels, %d photons, %d threads" % (texels, a.photons, a.threads))
        print("single bake: %.2f CPU s (wall: set-up %.2f, direct %.2f, photons+gather %.2f)"
              % (t_single, times["setup"], times["direct"], times["trace"]))
        print("CPU seconds:")
        print("%6s %10s %10s %10s %12s %20s %9s %s" % ("shards", "max shard", "sum shards", "merge", "parts (MB)",
                                                       "MB/part/M texels", "overhead", "identical"))
        for n in a.shards:
            parts = os.path.join(tmp, "parts%d" % n)
            shard_times, setups = [], []
            for k in range(1, n + 1):
                wall, out = run([a.photonlm, "bake", scene, "--shard", "%d/%d" % (k, n), "-o", parts,
                                 "--threads", str(a.threads)])
                shard_times.append(wall)
            size = sum(os.path.getsize(os.path.join(parts, p)) for p in os.listdir(parts))
            merged = os.path.join(tmp, "merged%d" % n)
            t_merge, _ = run([a.photonlm, "merge", parts, "-o", merged, "--threads", str(a.threads)])
            same = all(open(os.path.join(single_dir, f), "rb").read() == open(os.path.join(merged, f), "rb").read()
                       for f in os.listdir(single_dir) if f.endswith(".exr"))
            overhead = (sum(shard_times) + t_merge) / t_single - 1.0
            print("%6d %10.2f %10.2f %10.2f %12.1f %20.1f %8.1f%% %s"
                  % (n, max(shard_times), sum(shard_times), t_merge, size / 1e6, size / 1e6 / n / (texels / 1e6),
                     100 * overhead, "yes" if same else "NO"))
    finally:
        shutil.rmtree(tmp)


if __name__ == "__main__":
    main()
