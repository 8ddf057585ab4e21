#!/usr/bin/python3
"""Layer-mean pressure of the pool at rest (scenes/validation/hydrostatic_water.yaml), per frame.

Reads a run's HDF5 frames (datasets id, position, J), takes each particle's reference height
from frame 0, and prints per frame the mean pressure p = K / gamma (J^-gamma - 1) of each
layer (by reference height, `layers` of them) over the exact weight of the water above, as
mpm study's hydrostatic probe scores it (engine/tools/validation/cases.cpp). Bottom layer first.

Usage: /usr/bin/python3 scripts/pool_layers.py RUN_DIR [LAYERS]   (16: one cell of the scene)
Needs python3-h5py (Debian's Python, hence /usr/bin/python3).
"""
import glob
import sys

import h5py
import numpy as np

K, GAMMA, RHO, G = 4e5, 7.0, 1000.0, 9.81  # the scene's water and gravity
HEIGHT, AREA = 0.2, 0.2 * 0.1              # the pool's depth and floor, m and m^2


def main():
    run = sys.argv[1]
    layers = int(sys.argv[2]) if len(sys.argv) > 2 else 16
    files = sorted(glob.glob(run + "/frame_*.h5"))
    with h5py.File(files[0], "r") as f0:
        ids = f0["id"][:]
        y0 = np.empty(len(ids))
        y0[ids] = f0["position"][:, 1]
    heights = np.sort(y0)
    hi = np.searchsorted(heights, y0, "right")
    lo = np.searchsorted(heights, y0, "left")
    above = len(heights) - hi + 0.5 * (hi - lo - 1)  # half of those level with it
    mass = HEIGHT * AREA * RHO / len(y0)
    exact = mass * G * above / AREA
    layer = np.clip((y0 / HEIGHT * layers).astype(int), 0, layers - 1)
    for name in files[1:]:
        with h5py.File(name, "r") as f:
            p = np.empty(len(y0))
            p[f["id"][:]] = K / GAMMA * (f["J"][:] ** -GAMMA - 1)
        ratio = [p[layer == k].mean() / exact[layer == k].mean() for k in range(layers)]
        print(name.rsplit("/", 1)[-1], " ".join("%.3f" % r for r in ratio))


if __name__ == "__main__":
    main()
