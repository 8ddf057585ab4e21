#!/usr/bin/python3
"""Figures of the accuracy study from the CSV files `mpm study -o DIR` writes.

Usage: scripts/plot_study.py DIR [-o IMAGE_DIR] [--sandwater]
Writes IMAGE_DIR/accuracy_error_vs_time.png, accuracy_convergence.png, accuracy_drift.png and,
when the speed_* sweeps ran, accuracy_speed_options.png, and when the sand and water sweeps ran
(water_h, dam_break, collapse_h, repose), accuracy_sandwater.png (IMAGE_DIR defaults to
docs/images).
Needs Debian's python3-matplotlib (hence /usr/bin/python3).
"""
import argparse
import csv
import math
import os
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def order(hs, errors):
    """Least-squares slope of log(error) against log(h)."""
    xs = [math.log(h) for h in hs]
    ys = [math.log(e) for e in errors]
    n = len(xs)
    mx, my = sum(xs) / n, sum(ys) / n
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


def label(r):
    s = "%s %s" % (r["kernel"], r["sampling"])
    if r["experiment"] == "ppc":
        s = "ppc %s %s" % (r["ppc"], r["sampling"])
    elif r["experiment"] == "cfl":
        s = "cfl %s" % r["cfl"]
    elif r["experiment"].startswith("transfer"):
        s = r["transfer"]
    return s


def error_vs_time(rows, out):
    bar = [r for r in rows if r["case"] == "bar_vibration" and r["status"] == "ok"]
    fig, ax = plt.subplots(figsize=(7, 5))
    markers = {"h_convergence": "o", "ppc": "s", "cfl": "^", "transfer_bar": "D"}
    groups = defaultdict(list)
    for r in bar:
        groups[(r["experiment"], label(r) if r["experiment"] == "h_convergence" else "")].append(r)
    for (exp, lab), rs in sorted(groups.items()):
        ax.scatter([float(r["wall_seconds"]) for r in rs], [float(r["error"]) for r in rs],
                   marker=markers.get(exp, "x"), label=exp + (" " + lab if lab else ""), alpha=0.8)
    # Pareto front: no other run is both faster and more accurate.
    pts = sorted((float(r["wall_seconds"]), float(r["error"])) for r in bar)
    front, best = [], float("inf")
    for t, e in pts:
        if e < best:
            front.append((t, e))
            best = e
    ax.step([p[0] for p in front], [p[1] for p in front], where="post", color="k", lw=1.2,
            label="Pareto front")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time of the substeps, s (2 threads above 8192 particles, else 1)")
    ax.set_ylabel("first-mode period relative error")
    ax.set_title("Free-free bar, ten periods: error against time")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def convergence(rows, out):
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5))
    ax = axes[0]
    series = defaultdict(list)
    for r in rows:
        if r["experiment"] == "h_convergence" and r["status"] == "ok":
            series[(r["kernel"], r["sampling"])].append((float(r["h"]), float(r["error"])))
    for (kernel, sampling), pts in sorted(series.items()):
        pts.sort()
        hs, es = [p[0] for p in pts], [p[1] for p in pts]
        ax.loglog(hs, es, "o-", label="%s, %s: order %.2f" % (kernel, sampling, order(hs, es)))
    ax.set_xlabel("grid spacing h, m (bar length 1 m)")
    ax.set_ylabel("period relative error")
    ax.set_title("Bar period against h")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax = axes[1]
    pts = sorted((float(r["h"]), float(r["error"])) for r in rows
                 if r["experiment"] == "column_h" and r["status"] == "ok")
    if pts:
        hs, es = [p[0] for p in pts], [p[1] for p in pts]
        ax.loglog(hs, es, "o-", label="settled height: order %.2f" % order(hs, es))
    ax.set_xlabel("grid spacing h, m (column height 0.2 m)")
    ax.set_ylabel("relative error")
    ax.set_title("Resting column against h")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


def drift(series_rows, out):
    panels = [("transfer_spin", "angular momentum / initial", "Spinning cube: angular momentum"),
              ("transfer_bar", "energy / initial energy", "Bar (h = L/40): total energy"),
              ("collision", "kinetic energy / initial", "Colliding spheres: kinetic energy")]
    fig, axes = plt.subplots(1, 3, figsize=(14, 4.2))
    for ax, (exp, name, title) in zip(axes, panels):
        curves = defaultdict(lambda: ([], []))
        for r in series_rows:
            if r["experiment"] == exp and r["series"] == name:
                t, v = curves[r["label"].split()[-1]]
                t.append(float(r["t"]))
                v.append(float(r["value"]))
        for lab, (t, v) in sorted(curves.items()):
            ax.plot(t, v, label=lab)
        ax.set_xlabel("time, s")
        ax.set_ylabel(name)
        ax.set_title(title)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


SPEED_PANELS = [("speed_bar", "Bar: period relative error"),
                ("speed_spin", "Spinning cube: angular momentum drift"),
                ("speed_collision", "Colliding spheres: momentum drift / sphere"),
                ("speed_column", "Resting column: settled height error")]


def speed_options(rows, out):
    """Issue 15's speed options (the speed_* sweeps): error against wall time, one line per
    setting through its resolutions, in one panel per case. Returns False if none ran."""
    speed = [r for r in rows if r["experiment"].startswith("speed_") and r["status"] == "ok"]
    if not speed:
        return False
    fig, axes = plt.subplots(2, 2, figsize=(12, 9))
    colors = {"apic": "C0", "mls": "C1", "pic": "C2", "flip0.99": "C3"}
    for ax, (exp, title) in zip(axes.flat, SPEED_PANELS):
        lines = defaultdict(list)
        for r in speed:
            if r["experiment"] == exp:
                lines[(r["transfer"], r["grid_precision"], r["simd"])].append(
                    (float(r["h"]), float(r["wall_seconds"]), max(float(r["error"]), 1e-16)))
        for (transfer, grid, simd), pts in sorted(lines.items()):
            pts.sort(reverse=True)  # coarse to fine
            ax.plot([p[1] for p in pts], [p[2] for p in pts],
                    color=colors.get(transfer, "k"),
                    linestyle="-" if grid == "double" else "--",
                    marker="o" if simd == "true" else "s",
                    fillstyle="full" if simd == "true" else "none",
                    label="%s, %s grid, %s" % (transfer, grid,
                                               "simd" if simd == "true" else "scalar"))
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("wall time of the substeps, s (one study run; ratios only)")
        ax.set_ylabel("error")
        ax.set_title(title + " (each line: coarse to fine h)", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    return True


def sandwater(rows, out):
    """Issue 17's sweeps (water_h, dam_break, collapse_h, repose) in four panels. Returns False
    if none ran."""
    rs = [r for r in rows if r["experiment"] in ("water_h", "dam_break", "collapse_h", "repose")
          and r["status"] == "ok"]
    if not rs:
        return False
    fig, axes = plt.subplots(1, 4, figsize=(18, 4.2))
    ax = axes[0]
    pts = sorted((float(r["h"]), float(r["error"])) for r in rs if r["experiment"] == "water_h")
    if pts:
        hs, es = [p[0] for p in pts], [p[1] for p in pts]
        ax.loglog(hs, es, "o-", label="layer-mean RMS: order %.2f" % order(hs, es))
        ax.loglog(hs, [h / 0.2 for h in hs], "k--", label="h / H (the test's bound)")
    ax.set_xlabel("grid spacing h, m (depth H = 0.2 m)")
    ax.set_ylabel("pressure error / rho g H")
    ax.set_title("Still water column: p from J")
    ax = axes[1]
    for r in rs:
        if r["experiment"] != "dam_break":
            continue
        ax.scatter(float(r["wall_seconds"]), float(r["error"]))
        ax.annotate("%s h=%.4g" % (r["transfer"], float(r["h"])),
                    (float(r["wall_seconds"]), float(r["error"])), fontsize=7)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time of the substeps, s (one thread, loaded machine)")
    ax.set_ylabel("surge front RMS relative error")
    ax.set_title("Dam break against Martin & Moyce 1952")
    ax = axes[2]
    pts = sorted((float(r["h"]), float(r["error"])) for r in rs if r["experiment"] == "collapse_h")
    if pts:
        ax.loglog([p[0] for p in pts], [p[1] for p in pts], "o-",
                  label="a = 2 column, tan 30 friction")
    ax.set_xlabel("grid spacing h, m (L0 = 0.04 m)")
    ax.set_ylabel("runout relative error against Lube et al. 2005")
    ax.set_title("Column collapse runout against h")
    ax = axes[3]
    slopes = []
    for r in rs:
        if r["experiment"] != "repose":
            continue
        for m in r["measures"].split("; "):
            if m.startswith("slope_"):
                value, exact = m.split("=")[1].split(" (exact ")
                slopes.append((float(exact.rstrip(")")), float(value)))
    if slopes:
        slopes.sort()
        ax.plot([s[0] for s in slopes], [s[1] for s in slopes], "o-", label="deposit flank, a = 2")
        ax.plot([15, 45], [15, 45], "k--", label="repose angle atan(mu)")
    ax.set_xlabel("repose angle of the flow friction, degrees")
    ax.set_ylabel("flank slope, degrees")
    ax.set_title("Angle of the deposit's flank")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    return True


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("study_dir")
    ap.add_argument("-o", "--output", default="docs/images")
    ap.add_argument("--sandwater", action="store_true",
                    help="only accuracy_sandwater.png (a study of the sand and water sweeps)")
    args = ap.parse_args()
    rows = read(os.path.join(args.study_dir, "study.csv"))
    if args.sandwater:
        os.makedirs(args.output, exist_ok=True)
        sandwater(rows, os.path.join(args.output, "accuracy_sandwater.png"))
        print("wrote accuracy_sandwater.png in " + args.output)
        return
    series_rows = read(os.path.join(args.study_dir, "series.csv"))
    os.makedirs(args.output, exist_ok=True)
    error_vs_time(rows, os.path.join(args.output, "accuracy_error_vs_time.png"))
    convergence(rows, os.path.join(args.output, "accuracy_convergence.png"))
    drift(series_rows, os.path.join(args.output, "accuracy_drift.png"))
    written = "accuracy_error_vs_time.png, accuracy_convergence.png, accuracy_drift.png"
    if speed_options(rows, os.path.join(args.output, "accuracy_speed_options.png")):
        written += ", accuracy_speed_options.png"
    if sandwater(rows, os.path.join(args.output, "accuracy_sandwater.png")):
        written += ", accuracy_sandwater.png"
    print("wrote " + written + " in " + args.output)


if __name__ == "__main__":
    main()
