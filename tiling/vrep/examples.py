"""The V-models of Hong and Elber 2021 (Table 1, Figs. 6, 13-16) as analogues built from our primitives.

All lengths in model units (metres when analysed), all primitives paved with
the cross tile (7 trivariates per tile).  Conductivities ``k`` (W/(m K)) ride
on the maps as channels where a model is meant for heat analysis.

* :func:`box_cylinder`: a plate with a standing cylinder of higher priority
  pushed into it (Fig. 6, 5,992 trivariates in Table 1).
* :func:`cylinders`: three orthogonal solid cylinders A (along x), B (y), C
  (z), priorities A > B > C (Figs. 13-14).
* :func:`winged_duck`: two wings of higher priority unioned to the duck's body,
  a hole subtracted near the tail (Fig. 16, 39,070 trivariates): an
  aluminium body (k = 205) and steel wings (k = 54).
"""

from __future__ import annotations

from geometry.primitives import box
from geometry.shapes.examples import cylinder, duck

from .. import library as L
from .model import Primitive, VModel

__all__ = ["box_cylinder", "cylinders", "winged_duck", "WINGED_DUCK_TIPS"]

WINGED_DUCK_TIPS = ("wingL:vmax", "wingR:vmin")  # the wing tips' tags in :func:`winged_duck`'s micro-structure


def box_cylinder(plate=(14, 14, 3), cyl=(2, 2, 14)) -> VModel:
    """A 4 x 4 x 1 plate (priority 1) with a solid cylinder (radius 1, 3 long, priority 2) standing 0.7 deep in
    it; ``plate`` and ``cyl`` are the tile counts per knot span (the cylinder's map has 3 x 3 x 1 spans)."""
    P = Primitive(box((4.0, 4.0, 1.0), origin=(-2.0, -2.0, -1.0)), L.cross(), tuple(plate), 1, "box")
    C = Primitive(cylinder(1.0, 3.0, 2, centre=(0.0, 0.0, 0.8)), L.cross(), tuple(cyl), 2, "cyl")
    return P | C


def cylinders(counts=(1, 1, 12)):
    """The three orthogonal cylinders (A along x, radius 1; B along y, radius 1; C along z, radius 0.8; all 4
    long) with priorities A > B > C, as a tuple (A, B, C) to combine."""
    A = Primitive(cylinder(1.0, 4.0, 0), L.cross(), tuple(counts), 3, "A")
    B = Primitive(cylinder(1.0, 4.0, 1), L.cross(), tuple(counts), 2, "B")
    C = Primitive(cylinder(0.8, 4.0, 2), L.cross(), tuple(counts), 1, "C")
    return A, B, C


def winged_duck(body=(10, 10, 12), wing=(10, 20, 1), k_body: float = 205.0, k_wing: float = 54.0) -> VModel:
    """(body | left wing | right wing) - hole: the duck (2.1 long, :func:`geometry.shapes.examples.duck`, 1 x 1 x 5
    knot spans) paved ``body`` tiles per span; two 0.6 x 1.1 x 0.12 wings (biquadratic boxes) entering the body
    0.3 deep, paved ``wing`` per span, priorities 3 and 2 over the body's 1; a hole of radius 0.09 through the
    body near the tail.  Channels ``k`` per primitive."""
    B = Primitive(duck(channels={"k": k_body}), L.cross(), tuple(body), 1, "body")

    def one(y0, name, priority):
        W = box((0.6, 1.1, 0.12), origin=(0.75, y0, 0.22), degrees=(2, 2, 2), channels={"k": k_wing})
        return Primitive(W, L.cross(), tuple(wing), priority, name)

    hole = Primitive(cylinder(0.09, 1.0, 2, centre=(0.45, 0.0, 0.3)), L.cross(), (1, 1, 1), 4, "hole")
    return ((B | one(0.15, "wingL", 3)) | one(-1.25, "wingR", 2)) - hole
