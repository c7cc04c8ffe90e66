"""Speed-up from 1 to 2 (or more) threads on the benchmark scenes, per stage, with the CLI.

    /usr/bin/python3 docs/bench_threads.py [--pairs 5] [--threads 1 2] [--photons 8000000] [--json OUT.json]
    /usr/bin/python3 docs/bench_threads.py --plot OUT.png RUN.json [RUN.json ...]   # speed-up against threads

Scenes: the Cornell box (`photonlm cornell`: photon pass only; its printed bake and trace times)
and the open courtyard of 21 smooth spheres (docs/bench_open_courtyard.py --objects 21 --segments
32 --smooth --no-bake; `photonlm bake`, report.json "times": setup, direct pass, trace (photon pass
and final gather), total). Every bake traces a fixed photon count (no target, so each run does the
same work); runs of the thread counts are interleaved and the median of each stage is printed
with the speed-up over the first thread count.
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
STAGES = ("setup", "direct", "trace", "total")


def bake(cli, scene, threads, photons, out):
    subprocess.run([cli, "bake", scene, "-o", out, "--photons", str(photons), "--target-error", "0",
                    "--threads", str(threads), "--seed", "1"], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    with open(os.path.join(out, "report.json")) as f:
        return json.load(f)["times"]


def cornell(cli, _scene, threads, photons, out):
    text = subprocess.run([cli, "cornell", "--photons", str(photons), "--threads", str(threads), "--seed", "3",
                           "-o", out], check=True, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True).stdout
    m = re.search(r"bake ([0-9.]+) s \(trace ([0-9.]+) s\)", text)
    return {"trace": float(m.group(2)), "total": float(m.group(1))}


def plot(png, runs):
    """Speed-up of each scene's total against threads, one line per scene and run (label = file name)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4.2))
    top = 2
    for path in runs:
        with open(path) as f:
            run = json.load(f)
        for name, med in run["scenes"].items():
            threads = sorted(int(t) for t in med)
            speed = [med[str(threads[0])]["total"] / med[str(t)]["total"] for t in threads]
            top = max(top, threads[-1])
            ax.plot(threads, speed, "o-", label="%s (%s)" % (name, run.get("label", os.path.basename(path))))
    ax.plot([1, top], [1, top], "k:", lw=0.8, label="linear")
    ax.set_xscale("log", base=2)
    ax.set_yscale("log", base=2)
    ax.set_xlabel("threads")
    ax.set_ylabel("speed-up of the whole bake over 1 thread")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


def main():
    if len(sys.argv) > 2 and sys.argv[1] == "--plot":
        plot(sys.argv[2], sys.argv[3:])
        return
    ap = argparse.ArgumentParser()
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--photons", type=int, default=8_000_000)
    ap.add_argument("--photonlm", default=os.path.join(HERE, "..", "build", "bin", "photonlm"))
    ap.add_argument("--json", help="write the medians here (for --plot)")
    ap.add_argument("--label", default="", help="the machine, for --plot's legend")
    args = ap.parse_args()
    result = dict(label=args.label, photons=args.photons, pairs=args.pairs, scenes={})
    work = tempfile.mkdtemp(prefix="bench_threads_")
    court = os.path.join(work, "court")
    subprocess.run([sys.executable, os.path.join(HERE, "bench_open_courtyard.py"), "--out", court, "--objects",
                    "21", "--segments", "32", "--smooth", "--no-bake"], check=True, stdout=subprocess.DEVNULL)
    scenes = {"cornell box": (cornell, None, ("trace", "total")),
              "open courtyard (21 spheres)": (bake, os.path.join(court, "scene.json"), STAGES)}
    for name, (run, scene, stages) in scenes.items():
        runs = {t: [] for t in args.threads}
        for _ in range(args.pairs):
            for t in args.threads:
                runs[t].append(run(args.photonlm, scene, t, args.photons, os.path.join(work, "out")))
        med = {t: {s: statistics.median(r[s] for r in runs[t]) for s in stages} for t in args.threads}
        result["scenes"][name] = {str(t): m for t, m in med.items()}
        base = args.threads[0]
        print("%s, %d photons, median of %d" % (name, args.photons, args.pairs))
        for t in args.threads:
            print("  %2d threads: " % t + ", ".join("%s %.3f s (%.2fx)" % (s, med[t][s], med[base][s] / med[t][s])
                                                     for s in stages))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
