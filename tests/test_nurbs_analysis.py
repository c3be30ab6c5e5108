"""Analysis on exact NURBS patches uses the NURBS basis (iga.discretisation.rational), so it is exact where IGA is exact.

A patch whose geometry is its own rational spline (the exact annulus) holds every affine field of x in its
basis R = w N / W: a linear temperature and an affine displacement are reproduced and a free thermal expansion
is stress free, to round-off, at every refinement; Lame's thick cylinder converges at the optimal rates.
Composed rational patches (polynomial tiles in a NURBS map) keep the tile's polynomial basis: what holds there
exactly is a field affine in the map's parameters (checked below), while affine fields of x converge.
"""

import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from geometry.maps.inversion import invert
from iga import ElasticityProblem, HeatProblem
from tiling import library as L

G = np.array([3.0, -2.0, 5.0])
E, NU, ALPHA, DT = 70e9, 0.3, 2.3e-5, 50.0


def _annulus():
    return pr.annulus(0.5, 1.0, 0.4, exact=True)


def _random_points(spline, n=150, seed=0):
    return spline.evaluate(np.random.default_rng(seed).random((n, 3)))[:, :3]


@pytest.mark.parametrize("refine", [0, 1, 2, 3])
def test_a_linear_temperature_is_reproduced_on_the_exact_annulus(refine):
    A = _annulus()
    s = HeatProblem(A, refine=refine).dirichlet("boundary", lambda x: 1 + x @ G).solve()
    x = _random_points(A)
    span = float(np.ptp(x @ G))
    assert np.abs(s.probe(x) - (1 + x @ G)).max() <= 1e-9 * span  # 4.5e-3 at refine 0 in the polynomial basis
    assert s.h1_error(lambda x: np.broadcast_to(G, x.shape)) <= 1e-9 * np.linalg.norm(G)
    assert s.info["balance"]["relative_error"] < 1e-12 and s.energy_balance().relative_error < 1e-12


def test_two_nurbs_sectors_glued_by_their_shared_face_reproduce_a_linear_temperature():
    # the sectors' shared face has the same weights on both sides, so identity constraints on the NURBS
    # control values glue the NURBS bases
    parts = [pr.annulus(0.5, 1.0, 0.4, angle=np.pi / 2, start=a, exact=True) for a in (0.0, np.pi / 2)]
    s = HeatProblem(parts, refine=1).dirichlet("boundary", lambda x: 1 + x @ G).solve()
    x = np.concatenate([_random_points(p, 60, k) for k, p in enumerate(parts)])
    assert np.abs(s.probe(x) - (1 + x @ G)).max() <= 1e-9 * float(np.ptp(x @ G))


@pytest.mark.parametrize("refine", [0, 1, 2])
def test_affine_displacements_and_free_expansion_are_exact_on_the_exact_annulus(refine):
    A = _annulus()
    M = np.array([[1e-3, 2e-4, 0.0], [0.0, -5e-4, 1e-4], [3e-4, 0.0, 2e-4]])
    b = np.array([1e-4, 0.0, -2e-4])
    s = ElasticityProblem(A, E, NU, refine=refine).dirichlet("boundary", lambda x: x @ M.T + b).solve()
    x = _random_points(A)
    assert np.abs(s.displacement(x) - (x @ M.T + b)).max() <= 1e-9 * 1e-3
    free = ElasticityProblem(A, E, NU, refine=refine).thermal(DT, ALPHA, 0.0).hold_rigid().solve()
    assert free.von_mises(x).max() <= 1e-9 * E * ALPHA * DT  # 3.5e-2 E alpha dT in the polynomial basis
    assert free.strain_energy() <= 1e-12 * E * (ALPHA * DT) ** 2


def _lame(p_in=1e6, a=0.5, b=1.0):
    """Lame's thick cylinder under inner pressure, plane strain: radial displacement and hoop stress."""
    A_, B_ = p_in * a**2 / (b**2 - a**2), p_in * a**2 * b**2 / (b**2 - a**2)

    def u(x):
        r = np.hypot(x[:, 0], x[:, 1])
        ur = (1 + NU) / E * ((1 - 2 * NU) * A_ * r + B_ / r)
        return np.stack([ur * x[:, 0] / r, ur * x[:, 1] / r, np.zeros(len(x))], 1)

    def hoop(x):
        return A_ + B_ / (x[:, 0] ** 2 + x[:, 1] ** 2)

    return u, hoop


def test_lames_cylinder_converges_at_the_optimal_rates():
    # quarter of a thick cylinder (r 0.5 to 1), symmetry on the cut planes, plane strain along z, pressure
    # inside; degree 2 in the radius (one elevation): displacement error O(h^3) in L2, hoop stress O(h^2)
    u_exact, hoop_exact = _lame()
    x = _random_points(_annulus(), 200, 3)
    t = np.stack([-x[:, 1], x[:, 0], np.zeros(len(x))], 1) / np.hypot(x[:, 0], x[:, 1])[:, None]
    eu, es = [], []
    for refine in (1, 2, 3):
        s = (ElasticityProblem(_annulus(), E, NU, degree_elevation=(0, 1, 0), refine=refine)
             .dirichlet("umin", 0.0, "y").dirichlet("umax", 0.0, "x").dirichlet("wmin | wmax", 0.0, "z")
             .pressure("vmin", 1e6).solve())
        eu.append(s.l2_error(u_exact))
        S = s.stress(x)
        es.append(float(np.sqrt(np.mean((np.einsum("ni,nij,nj->n", t, S, t) - hoop_exact(x)) ** 2))))
    ru, rs = np.log2(eu[0] / eu[2]) / 2, np.log2(es[0] / es[2]) / 2
    assert ru >= 2.8 and rs >= 1.8, (eu, es, ru, rs)


def test_composed_rational_patches_reproduce_fields_affine_in_the_maps_parameters():
    # a cross lattice composed into the exact annulus: each tile keeps its own polynomial basis (Remark 2),
    # which holds every field affine in the tile's, hence in the map's, parameters
    D = _annulus()
    ms = tiling.regular(D, L.cross(), (2, 2, 1))
    c = np.array([2.0, -1.0, 0.5])

    def T(x):
        return 1 + invert(D, np.asarray(x, float)).params @ c

    s = HeatProblem(ms).dirichlet("boundary", T).solve()
    xi = np.random.default_rng(4).random((80, 3))
    inside = ms.patches[0].spline  # points of the first tile, mapped
    P = ms.patches[0]
    y = inside.evaluate(xi)[:, :3] @ P.placement[:, :3].T + P.placement[:, 3]
    x = D.evaluate(y)[:, :3]
    assert np.abs(s.probe(x) - (1 + y @ c)).max() <= 1e-9 * float(np.abs(c).sum())


def test_sectors_whose_weights_differ_by_one_factor_glue_and_unequal_weights_are_refused():
    # scaling all weights of a NURBS patch leaves its geometry and its basis unchanged: such sectors glue by
    # equal control values; weights that differ along a shared face would not glue, and are refused
    from geometry import BSpline
    from iga import ProblemError
    from iga.discretisation.constraints import _refuse_unequal_weights

    a = pr.annulus(0.5, 1.0, 0.4, angle=np.pi / 2, start=0.0, exact=True)
    b = pr.annulus(0.5, 1.0, 0.4, angle=np.pi / 2, start=np.pi / 2, exact=True)
    b3 = BSpline(b.degrees, b.knots, b.control_points, 3.0 * b.weights)
    s = HeatProblem([a, b3], refine=1).dirichlet("boundary", lambda x: 1 + x @ G).solve()
    x = _random_points(b, 60, 5)
    assert np.abs(s.probe(x) - (1 + x @ G)).max() <= 1e-9 * float(np.ptp(x @ G))
    offsets = np.array([0, 3, 6])
    with pytest.raises(ProblemError, match=r"patches 0 and 1 share a face on which their NURBS weights are not "
                                           r"proportional \(ratios 0.5 to 1\)"):
        _refuse_unequal_weights([np.array([1.0, 1.0, 1.0]), np.array([1.0, 2.0, 1.0])], offsets,
                                np.array([0, 1]), np.array([3, 4]))
