"""Open a written VTU (or a distributed run's .pvtu) in ParaView and check it: run with pvpython, not python.

    pvpython benchmarks/paraview_check.py heat-sink-out/heat_sink.vtu
    pvpython benchmarks/paraview_check.py out/heat_sink.pvtu --against serial/heat_sink.vtu

ParaView's own reader and filters (Debian's ``paraview`` package; pvpython 5.11
was used) read the file, extract its surface and count the boundary and
non-manifold edges of that surface: a welded mesh without internal faces
gives zero of both.  A ``.pvtu`` is read as one dataset by ParaView's parallel reader and welded by its
Clean to Grid filter (points on a rank boundary are in both pieces); with ``--against``, the welded
dataset must have the serial file's points, cells and point arrays, and its values at every point must
equal the serial file's there (to 1e-8 of their size).  Exits with status 1 otherwise.

On a machine without a display, run it under a virtual one: ``xvfb-run pvpython ...`` (Debian's ``xvfb``).
Debian's pvpython 5.11 segfaults with ``--force-offscreen-rendering``, so do not use that flag there.
"""

import sys

import numpy as np
from paraview import servermanager as sm
from paraview.simple import CleantoGrid, ExtractSurface, FeatureEdges, OpenDataFile
from vtkmodules.util.numpy_support import vtk_to_numpy


def _welded(path):
    """(ParaView source of the file, welded by Clean to Grid at 1e-9 of its size, and its data)."""
    reader = OpenDataFile(path)  # XMLPUnstructuredGridReader for .pvtu, XMLUnstructuredGridReader for .vtu
    reader.UpdatePipeline()
    b = sm.Fetch(reader).GetBounds()
    size = float(np.linalg.norm(np.array(b[1::2]) - np.array(b[::2])))
    clean = CleantoGrid(Input=reader)
    clean.ToleranceIsAbsolute = 1
    clean.AbsoluteTolerance = 1e-9 * size
    clean.UpdatePipeline()
    return clean, sm.Fetch(clean), size


def _edges(source) -> dict:
    surface = ExtractSurface(Input=source)
    surface.UpdatePipeline()
    counts = {"polygons": sm.Fetch(surface).GetNumberOfCells()}
    for kind in ("boundary", "non-manifold"):
        edges = FeatureEdges(Input=surface)
        edges.BoundaryEdges = int(kind == "boundary")
        edges.NonManifoldEdges = int(kind == "non-manifold")
        edges.FeatureEdges = 0
        edges.ManifoldEdges = 0
        edges.UpdatePipeline()
        counts[kind] = sm.Fetch(edges).GetNumberOfCells()
    return counts


def _arrays(data) -> dict:
    pd = data.GetPointData()
    return {pd.GetArrayName(i): vtk_to_numpy(pd.GetArray(i)) for i in range(pd.GetNumberOfArrays())}


def _order(points, size):
    """The points sorted by their coordinates rounded to 1e-7 of the model's size (the welding tolerance
    is far below it): two files with the same points list them in the same order."""
    q = np.round(points / (1e-7 * size)).astype(np.int64)
    return np.lexsort(q.T[::-1])


def compare(data, serial, size) -> list:
    """What differs between the welded dataset and the serial file: points, cells, arrays, values."""
    bad = []
    if data.GetNumberOfPoints() != serial.GetNumberOfPoints() or data.GetNumberOfCells() != serial.GetNumberOfCells():
        bad.append(f"{data.GetNumberOfPoints()} points / {data.GetNumberOfCells()} cells against the serial file's "
                   f"{serial.GetNumberOfPoints()} / {serial.GetNumberOfCells()}")
        return bad
    p, q = (vtk_to_numpy(d.GetPoints().GetData()) for d in (data, serial))
    i, j = _order(p, size), _order(q, size)
    gap = float(np.abs(p[i] - q[j]).max())
    if gap > 1e-8 * size:
        bad.append(f"points differ by up to {gap:.3g}")
    mine, theirs = _arrays(data), _arrays(serial)
    if set(theirs) - set(mine):
        bad.append(f"arrays missing: {sorted(set(theirs) - set(mine))}")
    for name in sorted(set(theirs) & set(mine)):
        if name == "heat_flux":  # averaged over the patches at a point: each piece's own side at a rank boundary
            continue
        a, b = mine[name][i], theirs[name][j]
        err = float(np.abs(a - b).max()) if a.size else 0.0
        if a.shape != b.shape or err > 1e-8 * max(float(np.abs(b).max()), 1e-300):
            bad.append(f"array {name!r} differs by up to {err:.3g}")
    return bad


def _refuse(argv) -> str | None:
    """What is wrong with the command line (a missing file, ``--against`` without one), or None."""
    import os

    usage = "usage: pvpython benchmarks/paraview_check.py FILE.vtu|FILE.pvtu [--against SERIAL.vtu]"
    if not argv or argv[0].startswith("--"):
        return usage
    if "--against" in argv and argv.index("--against") + 1 >= len(argv):
        return f"--against needs the serial .vtu to compare with; {usage}"
    files = [argv[0]] + ([argv[argv.index("--against") + 1]] if "--against" in argv else [])
    missing = [f for f in files if not os.path.isfile(f)]
    if missing:
        return f"no such file: {missing[0]} (give a .vtu or .pvtu written by iga run or iga.write_vtu)"
    return None


def main(argv):
    problem = _refuse(argv)
    if problem is not None:
        print(f"paraview_check: {problem}", file=sys.stderr)
        return 2
    path = argv[0]
    source, data, size = _welded(path)
    counts = _edges(source)
    print(f"{path}: {data.GetNumberOfCells()} cells, {data.GetNumberOfPoints()} points after welding; surface "
          f"{counts['polygons']} polygons, {counts['boundary']} boundary edges, "
          f"{counts['non-manifold']} non-manifold edges")
    ok = counts["boundary"] == counts["non-manifold"] == 0
    if "--against" in argv:
        other = argv[argv.index("--against") + 1]
        _, serial, _ = _welded(other)
        bad = compare(data, serial, size)
        print(f"against {other}: " + ("same points, cells, point arrays and values" if not bad else "; ".join(bad)))
        ok = ok and not bad
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
