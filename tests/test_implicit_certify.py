"""Connectivity of random implicit structures certified on the spline (tiling.implicit.certify).

The certificate's parts are checked against direct evaluation of the field
at random points and against a brute-force labelling of a fine sampling;
the promise it buys (Massarwi et al. 2018, Section 4: one connected
structure) against ``surface(r)`` at three samplings.
"""

import numpy as np
import pytest
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

import tiling
from geometry import SplineFunction, primitives
from tiling.implicit import boxes as ib
from tiling.implicit import certify as ic
from tiling.implicit.structure import _global_knots
from tiling.export import mesh_watertightness


@pytest.fixture(scope="module")
def duck():
    return primitives.duck()


def _random_field(counts, seed, degree=3, controls=6):
    """A random scalar field on the global C0 knots of ``counts`` cells, and its box grid (2 boxes per span)."""
    knots = [_global_knots(0.0, c, c, degree, controls) for c in counts]
    shape = tuple(len(U) - degree - 1 for U in knots)
    G = np.random.default_rng(seed).uniform(-1, 1, shape)
    return SplineFunction((degree,) * 3, knots, G[..., None]), G, ib.box_grid(knots, degree, counts, 2)


def _box_points(grid, knots, boxes, split, child, rng, n):
    """Random parameter points (L, n, 3) in child ``child`` of each box (L, 3) of the grid."""
    out = np.empty((len(boxes), n, 3))
    for k in range(3):
        edges = np.concatenate([np.linspace(a, b, 3)[:-1] for a, b in zip(np.unique(knots[k])[:-1],
                                                                          np.unique(knots[k])[1:])]
                               + [[knots[k][-1]]])
        lo, hi = edges[boxes[:, k]], edges[boxes[:, k] + 1]
        h = (hi - lo) / split
        out[..., k] = (lo + h * child[k])[:, None] + h[:, None] * rng.uniform(0, 1, (len(boxes), n))
    return out


@pytest.mark.parametrize("split", [1, 3])
def test_bounds_and_monotonicity_hold_at_random_points(split):
    f, G, grid = _random_field((2, 1, 2), seed=3)
    rng = np.random.default_rng(4)
    boxes = np.stack([rng.integers(0, n, 40) for n in grid.shape], 1)
    low, high, mono = ib.judge(G, grid, boxes, split)
    child = tuple(rng.integers(0, split, 3))
    x = _box_points(grid, f.knots, boxes, split, child, rng, 50)
    v = f.evaluate(x.reshape(-1, 3), compiled=False)[:, 0].reshape(len(boxes), -1)
    lo, hi = low[(slice(None),) + child], high[(slice(None),) + child]
    assert np.all(v >= lo[:, None] - 1e-12) and np.all(v <= hi[:, None] + 1e-12)
    assert np.any(v.min(1) - lo < 0.2)  # the bounds are also close where the box is small
    # a set bit: F rises (falls) along x_k between any two points of the child that differ in x_k only
    m = mono[(slice(None),) + child]
    assert np.count_nonzero(m) > 0
    for k in range(3):
        for bit, sgn in ((2 * k, 1), (2 * k + 1, -1)):
            pick = ((m >> bit) & 1).astype(bool)
            if not pick.any():
                continue
            a, b = x[pick].copy(), x[pick].copy()
            span = _box_points(grid, f.knots, boxes[pick], split, child, rng, 50)[..., k]
            a[..., k], b[..., k] = np.minimum(a[..., k], span), np.maximum(a[..., k], span)
            fa = f.evaluate(a.reshape(-1, 3), compiled=False)[:, 0]
            fb = f.evaluate(b.reshape(-1, 3), compiled=False)[:, 0]
            assert np.all(sgn * (fb - fa) >= -1e-12)


def test_bits_are_left_out_only_away_from_zero():
    f, G, grid = _random_field((1, 1, 1), seed=5)
    low, high, mono = ib.classify(G, grid)
    far = (low > ib.BAND) | (high < -ib.BAND)
    assert far.any() and not mono[far].any() and mono[~far].any()


def test_certified_boxes_are_joined_on_a_fine_sampling():
    # Soundness against brute force: on a random field (no connectivity steps), every positive sample of a box
    # the certificate accepts lies in the main positive component of a 40x finer sampling; and the boxes it
    # refuses include real islands.
    counts = (2, 2, 1)
    f, G, grid = _random_field(counts, seed=11)
    low, high, mono = ib.classify(G, grid)
    sign = ib.sign_at(low, high)
    ok = ic._certified(G, grid, sign, mono, 1, False, True)
    res = 80
    axes = [np.linspace(0, c, c * res + 1) for c in counts]
    F = f.evaluate_grid(axes)[..., 0]
    label, n = ndimage.label(F > 0)
    main_boxes = ic._main_component(sign, 1)
    main = np.unique(label[_box_of_samples(axes, grid, main_boxes) & (F > 0)])
    assert len(main) == 1  # the P boxes of the main component lie in one sampled component
    in_main = np.isin(label, main)
    accepted = _box_of_samples(axes, grid, ok)
    assert np.all(in_main[accepted & (F > 0)])
    refused = _box_of_samples(axes, grid, (sign >= 0) & ~ok)
    assert np.any(refused & (F > 0) & ~in_main)  # the certificate refuses where the samples see islands


def _box_of_samples(axes, grid, mask):
    """Samples (bool, grid of ``axes``) lying in a box of ``mask`` (2 boxes per unit span, 4 spans per cell)."""
    idx = [np.minimum((a * grid.per_cell[k]).astype(int), grid.shape[k] - 1) for k, a in enumerate(axes)]
    return mask[np.ix_(*idx)]


def _components(s, r, close, shipped=False):
    """Pieces of ``surface(r)``: ``shipped``, as shipped (the watertightness report); otherwise without the
    snapping of the vertices onto the exact zero set, which moves each along its grid edge and so leaves the
    pieces as they are (several times faster), counted as the connected components of the welded mesh's
    triangle graph (scipy.sparse.csgraph)."""
    if shipped:
        return mesh_watertightness(s.surface(r, close=close))["components"]
    mesh = s.surface(r, close=close, snap=False)
    mesh = mesh if mesh.is_all_triangles else mesh.triangulate()
    tri = mesh.faces.reshape(-1, 4)[:, 1:]
    n = mesh.n_points
    edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    count, label = connected_components(graph, directed=False)
    return len(np.unique(label[tri[:, 0]]))  # components that hold a triangle


@pytest.mark.slow
@pytest.mark.parametrize("seed", [pytest.param(0, marks=pytest.mark.kernel_sensitive), 1, 2, 3, 4])
def test_one_surface_at_every_sampling_on_a_443_grid(duck, seed):
    s = tiling.random_implicit(duck, (4, 4, 3), alpha=0.5, seed=seed, cap=True)
    assert s.stats["certificate"]["certified"], s.stats["certificate"]
    assert [_components(s, r, close=False, shipped=r == 12) for r in (12, 24, 48)] == [1, 1, 1]


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(5))
def test_uncapped_structures_are_certified_and_one_solid_at_the_build_sampling(duck, seed):
    # Uncapped, the zero set meets D's boundary; where it grazes a face, a sheet of the solid along the face can
    # be thinner than a finer sampling's step (seed 2: an 8-triangle piece at w = 1 at r = 24, joined at 12 and
    # 48). The certificate is about the spline, so it holds; the sampled surface is checked where it is built.
    s = tiling.random_implicit(duck, (4, 4, 3), alpha=0.5, seed=seed)
    record = s.stats["certificate"]
    assert record["certified"] and record["uncertified"] == 0, record
    # the solid's closed surface: the zero set and D's boundary where F > 0
    assert _components(s, 12, close=True, shipped=True) == 1


def _bent_box():
    """A (2, 1, 1) box bent by 0.2 sin(pi x / 2) in z (the control points of a cubic in x moved)."""
    from geometry import BSpline

    D = primitives.box((2.0, 1.0, 1.0), degrees=(3, 1, 3), elements=(4, 1, 1))
    cp = D.control_points.copy()
    cp[..., 2] += 0.2 * np.sin(np.pi * cp[..., 0] / 2)
    return BSpline(D.degrees, D.knots, cp)


@pytest.mark.slow
@pytest.mark.parametrize("seed", [1, pytest.param(7, marks=pytest.mark.kernel_sensitive)])
def test_c1_capped_structures_whose_held_faces_carry_islands_build_certified(seed):
    # With C1, an island of samples on a spanning-tree face whose coefficients are held cannot be bridged from
    # both cells (Eq. 8 ties each side's layer to the held face: a bridge on one side lowers the other), and
    # the two cells undid each other's bridges until the round limit refused the input (7 of seeds 1-8).
    # Such an island is left to the certificate, which proves the whole solid connected on the spline.
    s = tiling.random_implicit(_bent_box(), (4, 4, 3), degree=3, controls=6, continuity="C1", connectivity=2,
                               cap=True, alpha=0.5, seed=seed)
    record = s.stats["certificate"]
    assert record["certified"] and record["uncertified"] == 0 and record["near-critical held"] == 0, record
    assert _components(s, 12, close=False, shipped=False) == 1


@pytest.mark.slow
@pytest.mark.long
@pytest.mark.parametrize("seed", range(5))
def test_fig14_duck_capped_is_one_surface_at_every_sampling(duck, seed):
    s = tiling.random_implicit(duck, (4, 4, 12), alpha=0.5, seed=seed, continuity="C1", connectivity=2, cap=True)
    record = s.stats["certificate"]
    assert record["certified"] and record["uncertified"] == 0 and record["near-critical held"] == 0, record
    # r = 48 (21 million samples, 3.4 million triangles) for seed 0; the others at 12 and 24 (the suite's time);
    # benchmarks/random_tiling.py counts the pieces at 24 and 48 for its three cases, the uncapped duck's too
    samplings = (12, 24, 48) if seed == 0 else (12, 24)
    assert [_components(s, r, close=False, shipped=seed == 0 and r == 12) for r in samplings] == [1] * len(
        samplings)


def test_certificate_is_recorded_and_alpha_zero_needs_no_repair(duck):
    s = tiling.random_implicit(duck, (2, 2, 2), alpha=0.0, cap=True)
    record = s.stats["certificate"]
    assert record["certified"] and record["boxes"] == 30 ** 3 and record["per_cell"] == (15, 15, 15)
    assert record["raised"] == record["lowered"] == record["removed"] == record["near-critical"] == 0
