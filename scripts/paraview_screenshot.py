#!/usr/bin/pvpython
"""Renders one frame of a run with ParaView itself (frames.xmf, the default reader), as a PNG.

Usage: xvfb-run -a /usr/bin/pvpython scripts/paraview_screenshot.py RUN_DIR FRAME -o shot.png
           [--size 800 600] [--colour object_id]

Opens RUN_DIR/frames.xmf by its absolute path (a bare name makes ParaView 5.11 look for the
data files under wrong names, docs/output.md), shows the particles in the default Surface
representation (each particle is a vertex cell) as small spheres coloured by an attribute,
goes to the time of FRAME (the frame file's `time`) and saves the view. The camera looks
from the front (+z) and a little above at the centre of the particles' bounds. Needs
Debian's paraview and python3-paraview, and xvfb for a display (scripts/install-deps.sh).
"""
import argparse
import os
import sys

import h5py
from paraview.simple import (ColorBy, GetColorTransferFunction, GetActiveViewOrCreate,
                             OpenDataFile, Render, SaveScreenshot, Show)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run_dir")
    ap.add_argument("frame", type=int)
    ap.add_argument("-o", "--output", required=True)
    ap.add_argument("--size", type=int, nargs=2, default=[800, 600])
    ap.add_argument("--colour", default="object_id", help="point attribute to colour by")
    args = ap.parse_args()

    run = os.path.abspath(args.run_dir)
    with h5py.File(os.path.join(run, "frame_%05d.h5" % args.frame), "r") as h:
        t = float(h.attrs["time"])
    reader = OpenDataFile(os.path.join(run, "frames.xmf"))
    if reader is None:
        sys.exit("paraview_screenshot: cannot open %s/frames.xmf" % run)
    print("reader %s, %d time steps" % (reader.GetXMLName(), len(reader.TimestepValues)))
    reader.UpdatePipeline(t)

    view = GetActiveViewOrCreate("RenderView")
    view.ViewSize = args.size
    view.ViewTime = t
    view.OrientationAxesVisibility = 1
    view.Background = [1, 1, 1]
    if hasattr(view, "UseColorPaletteForBackground"):
        view.UseColorPaletteForBackground = 0
    shown = Show(reader, view)
    shown.SetRepresentationType("Surface")
    shown.PointSize = 3
    shown.RenderPointsAsSpheres = 1
    ColorBy(shown, ("POINTS", args.colour))
    lut = GetColorTransferFunction(args.colour)
    lut.ApplyPreset("Rainbow Uniform", True)
    shown.RescaleTransferFunctionToDataRange(True, False)

    info = reader.GetDataInformation()
    print("time %g: %d points, %d cells" % (t, info.GetNumberOfPoints(), info.GetNumberOfCells()))
    x0, x1, y0, y1, z0, z1 = info.GetBounds()
    centre = [(x0 + x1) / 2, (y0 + y1) / 2, (z0 + z1) / 2]
    size = max(x1 - x0, y1 - y0, z1 - z0)
    view.CameraFocalPoint = centre
    view.CameraPosition = [centre[0], centre[1] + 1.3 * size, centre[2] + 2.4 * size]
    view.CameraViewUp = [0, 1, 0]
    view.CameraViewAngle = 30
    Render(view)
    SaveScreenshot(args.output, view, ImageResolution=args.size)
    print("wrote %s" % args.output)


if __name__ == "__main__":
    main()
