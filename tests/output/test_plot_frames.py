#!/usr/bin/python3
"""scripts/plot_frames.py takes the walls from the run's scene and draws those seen edge-on.

Usage: /usr/bin/python3 tests/output/test_plot_frames.py SOURCE_DIR
Exits 1 with the failed checks listed.
"""
import os
import subprocess
import sys
import tempfile

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

src = sys.argv[1]
sys.path.insert(0, os.path.join(src, "scripts"))
import plot_frames  # noqa: E402

failures = []


def check(ok, what):
    if not ok:
        failures.append(what)


def lines_of(ax):
    """Every drawn line as ((x0, y0), (x1, y1)), rounded, ends sorted."""
    out = []
    for line in ax.get_lines():
        xs, ys = line.get_xdata(), line.get_ydata()
        ends = sorted([(round(float(xs[0]), 9), round(float(ys[0]), 9)),
                       (round(float(xs[-1]), 9), round(float(ys[-1]), 9))])
        out.append(tuple(ends))
    return out


# Walls at t = 1 s in a grid [0, 1] x [0, 2]: a floor, a right wall moving left at 0.1 m/s, a
# box on a keyframed path, and a plane tilted towards the viewer (not seen edge-on).
walls = [
    {"plane": {"point": [0, 0.05, 0], "normal": [0, 1, 0]}},
    {"plane": {"point": [0.9, 0, 0], "normal": [-2, 0, 0]}, "velocity": [-0.1, 0, 0]},
    {"box": {"min": [0.2, 0.3, 0.1], "max": [0.6, 1.5, 0.9]},
     "path": [[0, 0, 0, 0], [2, 0, 0.2, 0]]},
    {"plane": {"point": [0, 0, 0.5], "normal": [0, 0.1, 1]}},
]
fig, ax = plt.subplots()
hidden = plot_frames.draw_walls(ax, walls, 1.0, [0, 0, 0], [1, 2, 1])
lines = lines_of(ax)
check(((0.0, 0.05), (1.0, 0.05)) in lines, "the floor is the line y = 0.05 across: %s" % lines)
check(((0.8, 0.0), (0.8, 2.0)) in lines, "the moved right wall is the line x = 0.8: %s" % lines)
check(len(lines) == 2, "two plane lines, got %s" % lines)
check(hidden == ["plane 3"], "the tilted plane is named as not drawn, got %s" % hidden)
rects = [np.round(p.get_xy(), 9).tolist() for p in ax.patches if not p.get_fill()]
check(len(rects) == 1 and set(map(tuple, rects[0])) ==
      {(0.2, 0.4), (0.6, 0.4), (0.6, 1.6), (0.2, 1.6)},
      "the box, moved up 0.1 m on its path, is one outlined rectangle: %s" % rects)
# The solid sides are shaded: below the floor, right of the right wall, outside the box.
shaded = [p for p in ax.patches if p.get_fill()]
check(len(shaded) == 3, "three shaded solid regions, got %d" % len(shaded))
floor_shade = shaded[0].get_path()
check(floor_shade.contains_point((0.5, 0.02)) and not floor_shade.contains_point((0.5, 0.1)),
      "the floor's shade is below it")
wall_shade = shaded[1].get_path()
check(wall_shade.contains_point((0.9, 1.0)) and not wall_shade.contains_point((0.7, 1.0)),
      "the right wall's shade is right of it")
plt.close(fig)

# A whole run folder: the scene comes from report.yaml, the picture is written.
with tempfile.TemporaryDirectory() as tmp:
    scene = os.path.join(tmp, "scene.yaml")
    with open(scene, "w") as f:
        f.write("grid: {origin: [0, 0, 0], max: [1, 1, 1], dims: 10}\n"
                "walls:\n  - plane: {point: [0, 0.05, 0], normal: [0, 1, 0]}\n")
    run = os.path.join(tmp, "run")
    os.mkdir(run)
    with h5py.File(os.path.join(run, "frame_00000.h5"), "w") as h:
        h["position"] = np.random.default_rng(1).random((100, 3)).astype(np.float32)
        h["object_id"] = np.zeros(100, dtype=np.int32)
        h.attrs["time"] = 0.0
    script = os.path.join(src, "scripts", "plot_frames.py")
    png = os.path.join(tmp, "view.png")
    no_report = subprocess.run([sys.executable, script, run, "0", "-o", png],
                               capture_output=True, text=True)
    check(no_report.returncode != 0 and "--scene" in no_report.stderr,
          "without report.yaml it asks for --scene: %r" % no_report.stderr)
    with open(os.path.join(run, "report.yaml"), "w") as f:
        f.write("status: ok\nscene: %s\n" % scene)
    ok = subprocess.run([sys.executable, script, run, "0", "-o", png], capture_output=True,
                        text=True)
    check(ok.returncode == 0 and os.path.getsize(png) > 1000,
          "with report.yaml naming the scene it draws: %r" % ok.stderr)

if failures:
    print("test_plot_frames FAILED:")
    for f in failures:
        print("  " + f)
    sys.exit(1)
print("test_plot_frames: walls from the scene, drawn where they are")
