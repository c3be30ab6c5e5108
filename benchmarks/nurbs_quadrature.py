"""Exactness of the NURBS basis on the exact annulus against the Gauss points added per direction.

The NURBS basis R = w N / W (iga.discretisation.rational) holds every affine field of x, but its integrands are rational, so
the Galerkin solution reproduces a linear temperature only as well as the Gauss rule integrates them.  This
prints, per refinement of the exact quarter annulus (degree 2 along the arc, and elevated to 3), the largest
error of a linear temperature held on the boundary against the Gauss points added to p + 1, and the number
the toolkit adds (iga.discretisation.rational.rational_quadrature_extra, from W's variation over an element); the patch
tests ask for 1e-9.  It also prints, for the polynomial basis that a composed rational patch keeps (a cross
lattice in the same annulus), the stress of a free thermal expansion by refinement: it converges, it is not
zero.

    python benchmarks/nurbs_quadrature.py
"""

from __future__ import annotations

import numpy as np

import tiling
from geometry import primitives as pr
from iga import ElasticityProblem, HeatProblem
from iga.discretisation import setting as discretisation
from tiling import library as L

G = np.array([3.0, -2.0, 5.0])


def linear_error(refine: int, extra: int, elevation: int = 0) -> float:
    """The error with exactly ``extra`` Gauss points added (the toolkit's own choice replaced for the run)."""
    own = discretisation.rational_quadrature_extra
    discretisation.rational_quadrature_extra = lambda spline, space: extra
    try:
        A = pr.annulus(0.5, 1.0, 0.4, exact=True)
        s = HeatProblem(A, refine=refine, degree_elevation=elevation).dirichlet("boundary", lambda x: 1 + x @ G).solve()
    finally:
        discretisation.rational_quadrature_extra = own
    x = A.evaluate(np.random.default_rng(0).random((300, 3)))[:, :3]
    return float(np.abs(s.probe(x) - (1 + x @ G)).max() / np.ptp(x @ G))


def main() -> None:
    print("linear temperature on the exact annulus, max error / range, by Gauss points added (target 1e-9)")
    extras = (0, 1, 2, 3, 4, 5)
    print("degree refine " + "".join(f"{'+' + str(e):>9}" for e in extras) + "   toolkit adds")
    for elevation in (0, 1):
        for refine in range(5):
            A = pr.annulus(0.5, 1.0, 0.4, exact=True)
            own = HeatProblem(A, refine=refine, degree_elevation=elevation).spaces[0].dirs[0]
            print(f"{2 + elevation:>6} {refine:>6} " + "".join(f"{linear_error(refine, e, elevation):>9.1e}"
                                                            for e in extras) + f"   +{own.g - own.degree - 1}")
    print("\nfree thermal expansion (E 70 GPa, alpha 2.3e-5, dT 50 K) of a cross lattice in the exact annulus:")
    print("max von Mises / (E alpha dT) by refinement (the tiles keep their polynomial basis)")
    D = pr.annulus(0.5, 1.0, 0.4, exact=True)
    ms = tiling.regular(D, L.cross(), (2, 2, 1))
    x = None
    for refine in range(3):
        es = ElasticityProblem(ms, 70e9, 0.3, refine=refine).thermal(50.0, 2.3e-5, 0.0).hold_rigid().solve()
        if x is None:
            P = ms.patches[0]
            xi = np.random.default_rng(1).random((200, 3))
            x = D.evaluate(P.spline.evaluate(xi)[:, :3] @ P.placement[:, :3].T + P.placement[:, 3])[:, :3]
        print(f"  refine {refine}: {es.von_mises(x).max() / (70e9 * 2.3e-5 * 50.0):.2e}")


if __name__ == "__main__":
    main()
