"""Plot docs/bench_vs_cycles.py's JSON: error against seconds, log-log, one panel per scene.

    /usr/bin/python3 docs/plot_vs_cycles.py /tmp/bench/bench_vs_cycles.json docs/images/speed_vs_cycles.png

Solid: error against the plain Cycles reference (what a Cycles bake converges to: the value at
the texel centre). Dashed: error against the texel-average reference (Cycles at 4 x 4 texels per
texel, averaged; what photonlm converges to). Dotted, hollow: photonlm's own error estimate.
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(src, dst):
    with open(src) as f:
        data = json.load(f)
    scenes = data["scenes"]
    cols = min(3, len(scenes))
    rows = (len(scenes) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 4.6 * rows), squeeze=False)
    for ax in axes.flat[len(scenes):]:
        ax.set_visible(False)
    for ax, (name, r) in zip(axes.flat, scenes.items()):
        extra_legend = False
        series = [("cycles", "default", "tab:blue", "o", "Cycles"),
                  ("cycles", "no portal", "tab:cyan", "^", "Cycles without portal"),
                  ("photonlm", "default", "tab:red", "s", "photonlm")]
        for key, which, color, marker, label in series:
            order = (lambda x: x["samples"]) if key == "cycles" else (lambda x: x["seconds"])
            runs = sorted((x for x in r[key] if x.get("series", "default") == which), key=order)
            if not runs:
                continue
            if which == "no portal":
                extra_legend = True
            t = [x["seconds"] for x in runs]
            ax.loglog(t, [max(x["error"], 1e-4) for x in runs], "-", color=color, marker=marker,
                      label="%s vs Cycles reference" % label)
            if all(x.get("texel_average") for x in runs):
                ax.loglog(t, [max(x["texel_average"]["error"], 1e-4) for x in runs], "--", color=color,
                          marker=marker, mfc="none", alpha=0.7, label="%s vs texel-average reference" % label)
            for x in runs:
                tag = "%d" % x["samples"] if key == "cycles" else "%g" % x["target_error"]
                ax.annotate(tag, (x["seconds"], max(x["error"], 1e-4)), textcoords="offset points",
                            xytext=(4, 4 if key == "cycles" else -11), fontsize=7, color=color)
            if key == "photonlm":
                ax.loglog(t, [x["reported"] for x in runs], ":", color="black", marker="s", mfc="none",
                          ms=5, label="photonlm reported error")
        for lvl in (0.05, 0.02, 0.01):
            ax.axhline(lvl, color="gray", lw=0.6, ls="-.")
        ref = r["reference"]
        ax.set_title("%s (reference %d spp, noise %.1f %%)" % (name, ref["samples"], 100 * ref["noise"]), fontsize=10)
        ax.set_xlabel("seconds (operator wall time, 2 cores)")
        ax.set_ylabel("relative RMSE over covered texels")
        ax.grid(True, which="both", alpha=0.25)
        if extra_legend:
            ax.legend(fontsize=7, loc="upper right")
    axes[0][0].legend(fontsize=7, loc="lower left")
    fig.suptitle("Speed against error: photonlm vs Cycles (labels: Cycles samples / photonlm target error)",
                 fontsize=11)
    fig.tight_layout()
    fig.savefig(dst, dpi=110)
    print("wrote", dst)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
