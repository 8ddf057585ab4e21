#!/usr/bin/python3
"""Side views (x-y) of chosen frames of a run, as one PNG strip, with the scene's walls.

Usage: scripts/plot_frames.py OUTPUT_DIR FRAME [FRAME ...] -o picture.png [--scene SCENE]

The view looks along -z at the scene's grid box. Walls come from the scene: the one named
in OUTPUT_DIR/report.yaml (a path as given to `mpm run`, so absolute or relative to the folder
mpm ran in), or --scene (needed while the run is still going, when there is no report yet, or
when the run used --set on the walls or the grid). A plane whose normal lies in the x-y plane
is drawn as a line with its solid side shaded; a box as its x-y rectangle with the outside
shaded. A plane tilted towards the viewer covers the whole view and is only named in the
title. Moving walls are drawn where they are at each frame's time.
Needs Debian's python3-h5py, python3-matplotlib and python3-yaml (hence /usr/bin/python3).
"""
import argparse
import os
import sys

import h5py
import matplotlib
import yaml

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Circle, Polygon  # noqa: E402

WALL_COLOUR = "#555555"
SOLID_SHADE = "#bbbbbb"


def find_scene(run_dir, scene_option):
    """Path of the scene file: --scene, else the one report.yaml names."""
    if scene_option:
        return scene_option
    report = os.path.join(run_dir, "report.yaml")
    if not os.path.isfile(report):
        sys.exit("plot_frames: %s has no report.yaml (the run is still going or was not made "
                 "by mpm run): give the scene with --scene SCENE" % run_dir)
    with open(report) as f:
        scene = (yaml.safe_load(f) or {}).get("scene")
    if not scene:
        sys.exit("plot_frames: %s names no scene: give it with --scene SCENE" % report)
    if not os.path.isabs(scene) and not os.path.isfile(scene):
        sys.exit("plot_frames: the scene '%s' named in %s is relative to the folder mpm ran "
                 "in, and not found from here: give it with --scene SCENE" % (scene, report))
    return scene


def vec(value, what):
    if not (isinstance(value, list) and len(value) == 3):
        sys.exit("plot_frames: %s must be [x, y, z], got %r" % (what, value))
    return [float(c) for c in value]


def wall_offset(wall, t):
    """Displacement of a wall at time t: velocity * t, or its keyframed path (as the engine)."""
    path = wall.get("path") or []
    if not path:
        v = vec(wall.get("velocity", [0, 0, 0]), "wall velocity")
        return [t * c for c in v]
    keys = [(float(k[0]), [float(c) for c in k[1:4]]) for k in path]
    if t <= keys[0][0]:
        return keys[0][1]
    for (t0, a), (t1, b) in zip(keys, keys[1:]):
        if t <= t1:
            s = (t - t0) / (t1 - t0)
            return [(1 - s) * p + s * q for p, q in zip(a, b)]
    return keys[-1][1]


def clip_half_plane(poly, n, c):
    """The part of polygon `poly` (list of (x, y)) where n . p <= c (Sutherland-Hodgman)."""
    out = []
    for i, p in enumerate(poly):
        q = poly[(i + 1) % len(poly)]
        dp = n[0] * p[0] + n[1] * p[1] - c
        dq = n[0] * q[0] + n[1] * q[1] - c
        if dp <= 0:
            out.append(p)
        if (dp < 0 < dq) or (dq < 0 < dp):
            s = dp / (dp - dq)
            out.append((p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])))
    return out


def draw_walls(ax, walls, t, lo, hi):
    """Draws every wall visible in the x-y view at time t; returns the names of the others."""
    view = [(lo[0], lo[1]), (hi[0], lo[1]), (hi[0], hi[1]), (lo[0], hi[1])]
    hidden = []
    for k, wall in enumerate(walls):
        off = wall_offset(wall, t)
        if "plane" in wall:
            p = [a + b for a, b in zip(vec(wall["plane"]["point"], "plane point"), off)]
            n = vec(wall["plane"]["normal"], "plane normal")
            length = sum(c * c for c in n) ** 0.5
            if abs(n[2]) > 1e-9 * length:  # not seen edge-on: it fills the view
                hidden.append("plane %d" % k)
                continue
            c = n[0] * p[0] + n[1] * p[1]
            solid = clip_half_plane(view, n, c)  # the side the normal points away from
            if solid:
                ax.add_patch(Polygon(solid, closed=True, fc=SOLID_SHADE, ec="none", alpha=0.5,
                                     zorder=0))
            # The line itself: the edge of the solid side along n . p = c.
            edge = [q for q in solid if abs(n[0] * q[0] + n[1] * q[1] - c) <= 1e-9 * length *
                    max(1.0, abs(c))]
            if len(edge) >= 2:
                xs, ys = zip(*edge)
                ax.plot(xs, ys, color=WALL_COLOUR, lw=1.0, zorder=1)
        elif "box" in wall:
            bmin = [a + b for a, b in zip(vec(wall["box"]["min"], "box min"), off)]
            bmax = [a + b for a, b in zip(vec(wall["box"]["max"], "box max"), off)]
            rect = [(bmin[0], bmin[1]), (bmax[0], bmin[1]), (bmax[0], bmax[1]),
                    (bmin[0], bmax[1])]
            # The outside of the box is solid: shade the view minus the rectangle.
            ring = view + [view[0]] + [rect[0]] + rect[::-1]
            ax.add_patch(Polygon(ring, closed=True, fc=SOLID_SHADE, ec="none", alpha=0.5,
                                 zorder=0))
            ax.add_patch(Polygon(rect, closed=True, fill=False, ec=WALL_COLOUR, lw=1.0,
                                 zorder=1))
        elif "sphere" in wall:  # its x-y section through the centre
            c = [a + b for a, b in zip(vec(wall["sphere"]["center"], "sphere center"), off)]
            ax.add_patch(Circle((c[0], c[1]), float(wall["sphere"]["radius"]), fc=SOLID_SHADE,
                                ec=WALL_COLOUR, lw=1.0, alpha=0.5, zorder=0))
        else:  # mesh and vdb colliders are not drawn: named in the title instead
            hidden.append("%s %d" % ("mesh" if "mesh" in wall else "vdb", k))
    return hidden


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir")
    ap.add_argument("frames", nargs="+", type=int)
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--every", type=int, default=4, help="plot every n-th particle")
    ap.add_argument("--scene", help="the scene file (default: the one report.yaml names)")
    args = ap.parse_args()

    with open(find_scene(args.run_dir, args.scene)) as f:
        scene = yaml.safe_load(f)
    grid = scene.get("grid", {})
    lo = vec(grid.get("origin", [0, 0, 0]), "grid origin")
    hi = vec(grid["max"], "grid max")
    walls = scene.get("walls") or []

    fig, axes = plt.subplots(1, len(args.frames), figsize=(3 * len(args.frames), 3.2),
                             squeeze=False)
    colours = ["#e7298a", "#1b9e77", "#7570b3", "#d95f02", "#66a61e"]
    for ax, f in zip(axes[0], args.frames):
        with h5py.File(os.path.join(args.run_dir, "frame_%05d.h5" % f), "r") as h:
            x = h["position"][:: args.every]
            obj = h["object_id"][:: args.every]
            t = float(h.attrs["time"])
        hidden = draw_walls(ax, walls, t, lo, hi)
        for o in sorted(set(obj.tolist())):
            m = obj == o
            ax.scatter(x[m, 0], x[m, 1], s=0.3, c=colours[o % len(colours)], linewidths=0,
                       zorder=2)
        title = "frame %d, t = %.2f s" % (f, t)
        if hidden:
            title += "\n(not drawn: %s)" % ", ".join(hidden)
        ax.set_title(title, fontsize=9)
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal")
        ax.tick_params(labelsize=7)
    fig.tight_layout()
    fig.savefig(args.output, dpi=110)


if __name__ == "__main__":
    main()
