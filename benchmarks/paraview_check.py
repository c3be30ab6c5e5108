"""Open a written VTU in ParaView and count what Extract Surface gives: run with pvpython, not python.

    pvpython benchmarks/paraview_check.py heat-sink-out/heat_sink.vtu

ParaView's own reader and filters (Debian's ``paraview`` package; pvpython 5.11
was used) read the file, extract its surface and count the boundary and
non-manifold edges of that surface: a welded mesh without internal faces
gives zero of both.  Exits with status 1 otherwise.

On a machine without a display, run it under a virtual one: ``xvfb-run pvpython ...`` (Debian's ``xvfb``).
Debian's pvpython 5.11 segfaults with ``--force-offscreen-rendering``, so do not use that flag there.
"""

import sys

from paraview import servermanager as sm
from paraview.simple import ExtractSurface, FeatureEdges, XMLUnstructuredGridReader


def main(path):
    reader = XMLUnstructuredGridReader(FileName=[path])
    reader.UpdatePipeline()
    data = sm.Fetch(reader)
    surface = ExtractSurface(Input=reader)
    surface.UpdatePipeline()
    counts = {}
    for kind in ("boundary", "non-manifold"):
        edges = FeatureEdges(Input=surface)
        edges.BoundaryEdges = int(kind == "boundary")
        edges.NonManifoldEdges = int(kind == "non-manifold")
        edges.FeatureEdges = 0
        edges.ManifoldEdges = 0
        edges.UpdatePipeline()
        counts[kind] = sm.Fetch(edges).GetNumberOfCells()
    print(f"{path}: {data.GetNumberOfCells()} cells, {data.GetNumberOfPoints()} points; surface "
          f"{sm.Fetch(surface).GetNumberOfCells()} polygons, {counts['boundary']} boundary edges, "
          f"{counts['non-manifold']} non-manifold edges")
    return 0 if counts["boundary"] == counts["non-manifold"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
