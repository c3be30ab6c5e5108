"""Shapes built from splines: sweeps and offsets to a stated tolerance, trimmed surfaces, their
triangulation, stitching and outward orientation, interpolation, and the named example shapes."""
