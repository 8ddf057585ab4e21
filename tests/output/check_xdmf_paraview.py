#!/usr/bin/pvpython
"""Opens an XDMF index with ParaView's default reader and checks it against the frame files.

Usage: /usr/bin/pvpython tests/output/check_xdmf_paraview.py XMF

XMF is passed to OpenDataFile as given (say ./frames.xmf or an absolute path; a bare name
makes ParaView 5.11 look for the data files under wrong names, docs/output.md). The frame
files are the frame_*.h5 beside it, matched to the time steps by their `time` attribute.
Checks, and exits 1 with every mismatch listed if one fails:
- the reader ParaView chose is Xdmf3ReaderS (its default for .xmf), with one time step per
  frame file, at the files' times;
- at every time step, as many points as the frame has particles and one cell per particle,
  cell k holding just point k;
- at the middle time step, the points' positions and every other dataset of the frame file
  with one row per particle, as a point array of that name, with as many tuples and
  components and the same values.
"""
import glob
import os
import sys

import h5py
import numpy as np
from paraview.simple import OpenDataFile
from vtk.util.numpy_support import vtk_to_numpy

EXPECTED_READER = "Xdmf3ReaderS"


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    xmf = sys.argv[1]
    problems = []

    frames = {}  # time -> (file name, {dataset: array})
    for path in sorted(glob.glob(os.path.join(os.path.dirname(xmf) or ".", "frame_*.h5"))):
        with h5py.File(path, "r") as h:
            frames[float(h.attrs["time"])] = (
                os.path.basename(path), {name: h[name][()] for name in h.keys()})
    if len(frames) < 3:
        sys.exit("check_xdmf_paraview: need at least 3 frame files beside %s, found %d"
                 % (xmf, len(frames)))

    reader = OpenDataFile(xmf)
    if reader is None:
        sys.exit("check_xdmf_paraview: ParaView cannot open %s" % xmf)
    if reader.GetXMLName() != EXPECTED_READER:
        problems.append("reader is %s, not %s" % (reader.GetXMLName(), EXPECTED_READER))
    times = reader.TimestepValues
    times = list(times) if isinstance(times, (list, tuple)) or hasattr(times, "__len__") \
        else [times]
    file_times = sorted(frames)
    if len(times) != len(file_times):
        problems.append("%d time steps, %d frame files" % (len(times), len(file_times)))
    for t, ft in zip(times, file_times):
        if abs(t - ft) > 1e-12 * max(1.0, abs(ft)):
            problems.append("time step %r, frame file time %r" % (t, ft))

    middle = len(file_times) // 2
    for k, ft in enumerate(file_times):
        name, data = frames[ft]
        n = data["position"].shape[0]
        reader.UpdatePipeline(ft)
        grid = reader.GetClientSideObject().GetOutputDataObject(0)
        where = "%s (t = %r)" % (name, ft)
        if grid is None or not grid.IsA("vtkDataSet"):
            problems.append("%s: no data set" % where)
            continue
        if grid.GetNumberOfPoints() != n:
            problems.append("%s: %d points, %d particles" % (where, grid.GetNumberOfPoints(), n))
        if grid.GetNumberOfCells() != n:
            problems.append("%s: %d cells, %d particles" % (where, grid.GetNumberOfCells(), n))
        elif n > 0:
            cells = grid.GetCells()
            offsets = vtk_to_numpy(cells.GetOffsetsArray())
            connectivity = vtk_to_numpy(cells.GetConnectivityArray())
            if not (np.array_equal(offsets, np.arange(n + 1)) and
                    np.array_equal(connectivity, np.arange(n))):
                problems.append("%s: cell k does not hold just point k" % where)
        if k != middle:
            continue
        print("middle time step %r (%s): %d points, %d cells"
              % (ft, name, grid.GetNumberOfPoints(), grid.GetNumberOfCells()))
        if grid.GetNumberOfPoints() == n:
            points = vtk_to_numpy(grid.GetPoints().GetData())
            if not np.array_equal(points, data["position"]):
                problems.append("%s: point positions differ from the dataset position" % where)
        point_data = grid.GetPointData()
        for dataset, values in sorted(data.items()):
            if dataset == "position" or values.ndim == 0 or values.shape[0] != n:
                continue
            array = point_data.GetArray(dataset)
            if array is None:
                problems.append("%s: dataset %s is not a point array" % (where, dataset))
                continue
            components = 1 if values.ndim == 1 else values.shape[1]
            got = vtk_to_numpy(array)
            print("  %s: %d tuples x %d components (%s)"
                  % (dataset, array.GetNumberOfTuples(), array.GetNumberOfComponents(),
                     array.GetDataTypeAsString()))
            if array.GetNumberOfTuples() != n or array.GetNumberOfComponents() != components:
                problems.append("%s: %s has %d x %d values, the file %s"
                                % (where, dataset, array.GetNumberOfTuples(),
                                   array.GetNumberOfComponents(), values.shape))
            elif not np.array_equal(got.reshape(values.shape), values):
                problems.append("%s: %s differs from the file" % (where, dataset))

    if problems:
        print("check_xdmf_paraview: %s FAILED:" % xmf)
        for p in problems:
            print("  " + p)
        sys.exit(1)
    print("check_xdmf_paraview: %s: %d time steps, every particle a cell, every attribute "
          "read" % (xmf, len(file_times)))


if __name__ == "__main__":
    main()
