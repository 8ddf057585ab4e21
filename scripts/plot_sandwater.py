#!/usr/bin/python3
"""Figures of the sand and water validation (docs/validation.md, cases 10-12) from `mpm run`
output folders. Needs Debian's python3-h5py and python3-matplotlib (/usr/bin/python3).

  plot_sandwater.py collapse OUT.png LABEL:H:RUN_DIR ...   runout and height against a = H / L0
  plot_sandwater.py dambreak OUT.png LABEL:H:RUN_DIR ...   surge front against Martin & Moyce

H is the run's grid spacing (m): particles sit about h / 4 inside each face (8 per cell).

Column collapse: every object of scenes/validation/column_collapse.yaml is a symmetric column;
its half-width L0 and height come from frame 0 (particle extents plus the gap the sampling
leaves at a face, half a particle spacing), the runout and height from the last frame, as the
probe in engine/tools/validation/cases.cpp does. Prints one line per column.
"""
import glob
import os
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

# Martin & Moyce 1952, Phil. Trans. R. Soc. A 244, 312-324, Fig. 3, n^2 = 2, a = 2.25 in
# (digitised in PySPH, pysph/examples/db_exp_data.py): T = t sqrt(2 g / a), Z = x / a.
MM_T = [0.832, 1.219, 1.997, 2.547, 3.345, 4.034, 4.418, 5.091, 5.685]
MM_Z = [1.217, 1.474, 2.292, 2.995, 4.134, 4.944, 5.881, 6.980, 7.945]


def frames(run_dir):
    return sorted(glob.glob(os.path.join(run_dir, "frame_*.h5")))


def column_results(run_dir, h):
    """(a, runout (L - L0) / L0, height H / L0) per object."""
    f = frames(run_dir)
    first, last = h5py.File(f[0], "r"), h5py.File(f[-1], "r")
    x0, obj0 = first["position"][:], first["object_id"][:]
    x1, obj1 = last["position"][:], last["object_id"][:]
    gap = h / 4  # 8 particles per cell: the sub-cell centres sit h / 4 inside each face
    floor = x0[:, 1].min() - gap
    out = []
    for o in np.unique(obj0):
        a0, a1 = x0[obj0 == o], x1[obj1 == o]
        lo, hi = a0[:, 0].min() - gap, a0[:, 0].max() + gap
        L0, centre = (hi - lo) / 2, (hi + lo) / 2
        H0 = a0[:, 1].max() + gap - floor
        runout = ((a1[:, 0].max() + gap - centre) + (centre - a1[:, 0].min() + gap)) / 2
        # Flank slope: the surface height (highest particle per h-wide bin of |x - centre|,
        # both sides folded) fitted by a line where it is between 20 % and 80 % of the top.
        r = np.abs(a1[:, 0] - centre)
        bins = np.floor(r / h).astype(int)
        top = np.full(bins.max() + 1, np.nan)
        for b, y in zip(bins, a1[:, 1] + gap - floor):
            top[b] = y if np.isnan(top[b]) else max(top[b], y)
        rb = (np.arange(len(top)) + 0.5) * h
        ok = ~np.isnan(top) & (top > 0.2 * np.nanmax(top)) & (top < 0.8 * np.nanmax(top))
        slope = np.degrees(np.arctan(-np.polyfit(rb[ok], top[ok], 1)[0])) if ok.sum() >= 3 else np.nan
        # Has it stopped? The fastest particle at the last frame, and the runout's change over
        # the last 0.25 s (5 frames of 0.05 s).
        ap = h5py.File(f[max(0, len(f) - 6)], "r")
        xp = ap["position"][:][ap["object_id"][:] == o]
        runout_p = ((xp[:, 0].max() + gap - centre) + (centre - xp[:, 0].min() + gap)) / 2
        vmax = np.linalg.norm(last["velocity"][:][obj1 == o], axis=1).max()
        out.append((H0 / L0, (runout - L0) / L0, (a1[:, 1].max() + gap - floor) / L0, slope,
                    vmax, (runout - runout_p) / L0))
    return sorted(out)


def lube_runout(a):
    return np.where(a <= 2.3, 1.2 * a, 1.9 * a ** (2 / 3))


def lube_height(a):
    return np.where(a < 1.15, a, a**0.4)


def collapse(out_png, runs):
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    a = np.geomspace(0.4, 10, 100)
    ax1.plot(a[a < 1.8], 1.2 * a[a < 1.8], "k-", label="Lube et al. 2005: 1.2 a")
    ax1.plot(a[a > 2.8], 1.9 * a[a > 2.8] ** (2 / 3), "k--", label="Lube et al. 2005: 1.9 a^(2/3)")
    ax2.plot(a[a < 1.15], a[a < 1.15], "k-", label="Lube et al. 2005: a")
    ax2.plot(a[a > 1.15], a[a > 1.15] ** 0.4, "k--", label="Lube et al. 2005: a^(2/5)")
    ax2.plot(a[a > 1.15], 0.88 * a[a > 1.15] ** (1 / 3), "k:", label="0.88 a^(1/3) (unverified)")
    for label, h, run_dir in runs:
        res = column_results(run_dir, h)
        for ai, r, hh, slope, vmax, drift in res:
            print(f"{label}: a = {ai:.2f}  runout {r:.3f} (Lube {float(lube_runout(ai)):.3f})"
                  f"  height {hh:.3f} (Lube {float(lube_height(ai)):.3f})"
                  f"  flank slope {slope:.1f} deg  last frame: max speed {vmax:.3f} m/s,"
                  f" runout change over 0.25 s {drift:+.3f} L0")
        A = [x[0] for x in res]
        ax1.plot(A, [x[1] for x in res], "o-", label=label)
        ax2.plot(A, [x[2] for x in res], "o-", label=label)
    for ax, name in ((ax1, "runout (L - L0) / L0"), (ax2, "final height H / L0")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("aspect ratio a = H0 / L0")
        ax.set_ylabel(name)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("Granular column collapse, MPM sand (Drucker-Prager) against experiments")
    fig.tight_layout()
    fig.savefig(out_png, dpi=110)


def dambreak(out_png, runs):
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(MM_T, MM_Z, "ks", label="Martin & Moyce 1952, n^2 = 2")
    for label, h, run_dir in runs:
        T, Z = [], []
        x0 = None
        for f in frames(run_dir):
            d = h5py.File(f, "r")
            x = d["position"][:]
            if x0 is None:
                # the column's width a and left face, from frame 0 (faces h / 4 outside)
                left, right = x[:, 0].min() - h / 4, x[:, 0].max() + h / 4
                a, x0 = right - left, left
            t = float(d.attrs["time"])
            T.append(t * np.sqrt(2 * 9.81 / a))
            Z.append((x[:, 0].max() + h / 4 - x0) / a)
        ax.plot(T, Z, "-", label=label)
    ax.set_xlabel("T = t sqrt(2 g / a)")
    ax.set_ylabel("surge front Z = x / a")
    ax.set_xlim(0, 4.5)
    ax.set_ylim(1, 6.5)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Dam break: surge front")
    fig.tight_layout()
    fig.savefig(out_png, dpi=110)


if __name__ == "__main__":
    what, out_png = sys.argv[1], sys.argv[2]
    runs = []
    for arg in sys.argv[3:]:
        label, h, run_dir = arg.split(":", 2)
        runs.append((label, float(h), run_dir))
    {"collapse": collapse, "dambreak": dambreak}[what](out_png, runs)
