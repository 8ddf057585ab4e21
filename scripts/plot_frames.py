#!/usr/bin/python3
"""Side views (x-y) of chosen frames of a run, as one PNG strip.

Usage: scripts/plot_frames.py OUTPUT_DIR FRAME [FRAME ...] -o picture.png
Needs Debian's python3-h5py and python3-matplotlib (hence /usr/bin/python3).
"""
import argparse
import os

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir")
    ap.add_argument("frames", nargs="+", type=int)
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--every", type=int, default=4, help="plot every n-th particle")
    args = ap.parse_args()
    fig, axes = plt.subplots(1, len(args.frames), figsize=(3 * len(args.frames), 3.2))
    if len(args.frames) == 1:
        axes = [axes]
    colours = ["#e7298a", "#1b9e77", "#7570b3", "#d95f02", "#66a61e"]
    for ax, f in zip(axes, args.frames):
        with h5py.File(os.path.join(args.run_dir, "frame_%05d.h5" % f), "r") as h:
            x = h["position"][:: args.every]
            obj = h["object_id"][:: args.every]
            t = h.attrs["time"]
        for o in sorted(set(obj.tolist())):
            m = obj == o
            ax.scatter(x[m, 0], x[m, 1], s=0.3, c=colours[o % len(colours)], linewidths=0)
        ax.set_title("frame %d, t = %.2f s" % (f, t), fontsize=9)
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1)
        ax.set_aspect("equal")
        ax.axhline(0.05, color="grey", lw=0.8)
        ax.tick_params(labelsize=7)
    fig.tight_layout()
    fig.savefig(args.output, dpi=110)


if __name__ == "__main__":
    main()
