"""The engine's refinement of the courtyard's subdivision cages alone (no Blender), with 1 and 2
threads: as the scene has them (128 copies of one monkey: one topology, so one shared refinement
plan) and with every cage given a topology of its own (its faces listed from another first face:
the same surface, nothing shared).

    blender -b --factory-startup --python docs/bench_courtyard.py -- --out /tmp/cy --export-only --bakes 1 --scene-file
    PHOTONLM_LIBRARY=build/lib/libphotonlm.so PYTHONPATH=python_bridge \\
        /usr/bin/python3 docs/bench_refine.py /tmp/cy/scene/courtyard.json [--rounds 5]

Each round adds the cages (plm_scene_add_subdiv_mesh: checks and copies, shaded smooth) and
refines them (plm_scene_refine_subdiv_meshes) once per thread count, interleaved; printed: the
medians of the add calls' and the refinement's wall and CPU seconds (process CPU: all threads).
"""
import argparse
import json
import statistics
import time

import numpy as np

import photonlm


def read_cages(path):
    with open(path) as f:
        d = json.load(f)
    out = []
    for m in d["meshes"]:
        if "subdivision" not in m:
            continue
        out.append(dict(name=m["name"], positions=np.array(m["positions"], np.float32).reshape(-1, 3),
                        sizes=np.array(m["subdivision"]["face_sizes"], np.uint32),
                        indices=np.array(m["indices"], np.uint32), level=int(m["subdivision"]["level"]),
                        uv=np.array(m["lightmap_uv"], np.float32).reshape(-1, 2)))
    return out


def own_topology(cage, k):
    """The cage with its faces listed from face k on: the same surface, another topology."""
    sizes = cage["sizes"].astype(np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    order = np.roll(np.arange(len(sizes)), k % len(sizes))
    corners = np.concatenate([np.arange(starts[f], starts[f] + sizes[f]) for f in order])
    return dict(cage, sizes=cage["sizes"][order].copy(), indices=cage["indices"][corners].copy(),
                uv=cage["uv"][corners].copy())


def refine(cages, threads):
    s = photonlm.Scene()
    try:
        s.add_material((0.5, 0.5, 0.5), (0, 0, 0), name="grey")
        t0, c0 = time.perf_counter(), time.process_time()
        for c in cages:
            mid = s.add_subdiv_mesh(c["name"], c["positions"], c["sizes"], c["indices"], c["level"],
                                    lightmap_uv=c["uv"], resolution=64)
            s.set_mesh_smooth(mid)
        t1, c1 = time.perf_counter(), time.process_time()
        s.refine_subdiv_meshes(threads)
        return t1 - t0, c1 - c0, time.perf_counter() - t1, time.process_time() - c1
    finally:
        s.close()


def main():
    ap = argparse.ArgumentParser(prog="bench_refine.py")
    ap.add_argument("scene", help="a courtyard scene file (bench_courtyard.py --scene-file)")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    args = ap.parse_args()
    shared = read_cages(args.scene)
    distinct = [own_topology(c, k) for k, c in enumerate(shared)]
    triangles = sum(2 * int(c["sizes"].sum()) * 4 ** (c["level"] - 1) for c in shared)
    for label, cages in (("copies of one topology", shared), ("a topology each", distinct)):
        runs = {t: [] for t in args.threads}
        for _ in range(args.rounds):
            for t in args.threads:
                runs[t].append(refine(cages, t))
        for t, r in runs.items():
            med = [statistics.median(x[i] for x in r) for i in range(4)]
            print("%d cages, %s, %d thread(s): add %.3f s (CPU %.3f s); refine %.3f s (%.3f-%.3f), CPU %.3f s "
                  "= %.2f CPU s per M triangles" % (len(cages), label, t, med[0], med[1], med[2],
                                                     min(x[2] for x in r), max(x[2] for x in r), med[3],
                                                     med[3] / (triangles / 1e6)), flush=True)


if __name__ == "__main__":
    main()
