#!/usr/bin/python3
"""Fragments of a run's frame and the plastic Jp of its snow, as tests/physics/fragments.h counts
them: particles binned into cubic cells of edge CELL (m), face-sharing occupied cells joined.

Usage: /usr/bin/python3 scripts/snow_fragments.py RUN_DIR FRAME CELL [--plot OUT.png]
FRAME is a frame number, several joined by commas, or "all". --plot draws the last FRAME's
particles seen from above (x, z) and from the side (x, y), the four largest fragments in
colour and the rest (dust, specks) in grey.
Prints, per frame, the fragment count, the largest fragment's share and the largest sizes,
whether it meets the shatter criterion (docs/validation.md, section 17), and for each of the
three largest fragments its share, bounding box and mean velocity (a heap of dust against a
wall shows as a thin box at the wall, at rest);
then, from RUN_DIR/checkpoint.h5 (the last frame's state), the share of particles with Jp > 1,
Jp's range, and the "intact pieces": the fragments of the particles whose hardness
exp(xi (1 - Jp)) is still at least 1% of the virgin snow's (Jp <= 1 + ln(100) / 10 for
xi = 10), i.e. chunks that only failed, cohesionless snow joins."""
import os
import sys

import h5py
import numpy as np
from scipy import ndimage

run, frames, cell = sys.argv[1], sys.argv[2], float(sys.argv[3])
plot = sys.argv[sys.argv.index("--plot") + 1] if "--plot" in sys.argv else None


def labelled(x):
    """Each point's fragment label (points x, N x 3) and the fragments' sizes by label."""
    ijk = np.floor(x / cell).astype(np.int64)
    ijk -= ijk.min(axis=0)
    occupied = np.zeros(ijk.max(axis=0) + 1, bool)
    occupied[tuple(ijk.T)] = True
    labels, _ = ndimage.label(occupied)  # default structure: face neighbours only
    point_labels = labels[tuple(ijk.T)]
    return point_labels, np.bincount(point_labels)


def fragments(x):
    """Fragment sizes, largest first, of the points x (N x 3)."""
    return np.sort(labelled(x)[1][1:])[::-1]


if frames == "all":
    numbers = sorted(int(name[6:11]) for name in os.listdir(run)
                     if name.startswith("frame_") and name.endswith(".h5"))
else:
    numbers = [int(n) for n in frames.split(",")]
for frame in numbers:
    with h5py.File(os.path.join(run, f"frame_{frame:05d}.h5")) as f:
        x = f["position"][:].astype(np.float64)
        v = f["velocity"][:].astype(np.float64)
        t = float(f.attrs["time"])
    point_labels, by_label = labelled(x)
    order = np.argsort(by_label[1:])[::-1] + 1  # the fragments' labels, largest first
    sizes = by_label[order]
    print(f"frame {frame} (t = {t:.4f} s): {len(x)} particles, {len(sizes)} fragments, largest "
          f"{sizes[0] / len(x):.1%}, sizes {sizes[:6].tolist()}")
    # The shatter criterion of docs/validation.md section 17 (test::shattered).
    shattered = sizes[0] < 0.6 * len(x) and (sizes >= 0.02 * len(x)).sum() >= 3
    print(f"shatters (largest < 60%, >= 3 fragments of >= 2%): {'yes' if shattered else 'no'}")
    for label in order[:3]:
        inside = point_labels == label
        lo, hi, mean_v = x[inside].min(axis=0), x[inside].max(axis=0), v[inside].mean(axis=0)
        print(f"  {inside.sum() / len(x):.1%}: box {np.round(lo, 3).tolist()} to "
              f"{np.round(hi, 3).tolist()} m, mean velocity {np.round(mean_v, 2).tolist()} m/s")
if plot:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    # The last frame's fragments, largest first: colours for the four largest, grey the rest.
    rank = np.empty(len(by_label), np.int64)
    rank[order] = np.arange(len(order))
    piece = rank[point_labels]
    colours = ["#1f4e9c", "#d62728", "#2ca02c", "#ff7f0e"]
    fig, axes = plt.subplots(2, 1, figsize=(8, 8))
    for ax, (a, name) in zip(axes, [(2, "z"), (1, "y")]):
        rest = piece >= len(colours)
        ax.scatter(x[rest, 0], x[rest, a], s=0.2, c="0.75", lw=0, label="the rest (dust)")
        for k, colour in enumerate(colours):
            inside = piece == k
            if inside.any():
                ax.scatter(x[inside, 0], x[inside, a], s=0.4, c=colour, lw=0,
                           label=f"fragment {k + 1}: {inside.mean():.1%}")
        ax.set_ylabel(f"{name} (m)")
        ax.set_aspect("equal")
    axes[0].set_title(f"{os.path.basename(os.path.normpath(run))}, t = {t:.3f} s: "
                      f"fragments (cells of edge {cell:g} m)")
    axes[0].legend(loc="upper right", markerscale=12, fontsize=8)
    for ax in axes:
        ax.set_xlabel("x (m)")
    fig.tight_layout()
    fig.savefig(plot, dpi=110)
    print(f"plot: {plot}")
checkpoint = os.path.join(run, "checkpoint.h5")
if os.path.exists(checkpoint):
    with h5py.File(checkpoint) as f:
        if "material_state_0" in f:
            Jp = f["material_state_0"][:]
            print(f"last frame: Jp > 1 for {(Jp > 1).mean():.1%}, Jp in [{Jp.min():.3f}, "
                  f"{Jp.max():.3g}], median {np.median(Jp):.3f}")
            intact = f["x"][:][Jp <= 1 + np.log(100) / 10]
            n = len(Jp)
            if len(intact):
                pieces = fragments(intact)
                print(f"intact pieces: {len(intact) / n:.1%} of the particles intact, largest "
                      f"piece {pieces[0] / n:.1%}, pieces of >= 1%: {(pieces >= 0.01 * n).sum()}, "
                      f"sizes {pieces[:6].tolist()}")
