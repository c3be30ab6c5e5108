"""Anchoring-face matching (Hong and Elber 2021, Algorithms 1-2) against brute force on small instances."""

import itertools

import numpy as np
import pytest

from tiling import TilingError
from tiling.vrep.matching import edge_weights, geom_filter, hungarian, unbalanced_match


def _brute(W, allowed=None):
    """(most valid pairs, least weight) over every partial assignment, by enumeration."""
    valid = np.isfinite(W) if allowed is None else (np.isfinite(W) & allowed)
    M, N = W.shape
    best = (0, 0.0)
    rows = range(M)
    for k in range(1, min(M, N) + 1):
        for rs in itertools.combinations(rows, k):
            for cs in itertools.permutations(range(N), k):
                if all(valid[r, c] for r, c in zip(rs, cs)):
                    s = float(sum(W[r, c] for r, c in zip(rs, cs)))
                    if k > best[0] or (k == best[0] and s < best[1] - 1e-12):
                        best = (k, s)
    return best


def _instance(rng, M, N):
    Pm = rng.uniform(-1, 1, (M, 3)) + [0, 0, -1.0]
    Pn = rng.uniform(-1, 1, (N, 3)) + [0, 0, 1.0]
    Dm = np.tile([0, 0, 1.0], (M, 1)) + 0.4 * rng.standard_normal((M, 3))
    Dn = np.tile([0, 0, -1.0], (N, 1)) + 0.4 * rng.standard_normal((N, 3))
    return Pm, Dm, Pn, Dn


@pytest.mark.parametrize("seed", range(12))
def test_both_stages_equal_the_brute_force_optimum(seed):
    rng = np.random.default_rng(seed)
    M, N = int(rng.integers(2, 6)), int(rng.integers(1, 4))
    Pm, Dm, Pn, Dn = _instance(rng, max(M, N), min(M, N))
    W = edge_weights(Pm, Dm, Pn, Dn, d_maxdist=2.5)
    m = unbalanced_match(Pm, Dm, Pn, Dn, d_maxdist=2.5)
    got1 = (len(m.first), sum(W[i, j] for i, j in m.first))
    assert got1[0] == _brute(W)[0] and got1[1] == pytest.approx(_brute(W)[1], abs=1e-9)
    used = {i for i, _ in m.first}
    rest = np.array([i not in used for i in range(len(Pm))])
    allowed = geom_filter(Pm, Pn, Dn, rest[:, None] & np.isfinite(W), m.first)
    got2 = (len(m.second), sum(W[i, j] for i, j in m.second))
    b2 = _brute(W, allowed)
    assert got2[0] == b2[0] and got2[1] == pytest.approx(b2[1], abs=1e-9)
    # no face receives more than two bridges, and every two-to-one pair passed GeomFilter
    counts = np.bincount([j for _, j in m.first + m.second], minlength=len(Pn))
    assert counts.max() <= 2
    assert all(allowed[i2, j] for j, (_, i2) in m.two_to_one.items())


def test_invalid_edges_are_never_matched():
    Pm = np.array([[0, 0, 0.0], [5, 0, 0.0]])
    Pn = np.array([[0, 0, 1.0]])
    D = np.array([[0, 0, 1.0]])
    m = unbalanced_match(Pm, np.tile(D, (2, 1)), Pn, -D, d_maxdist=2.0)
    assert m.first == [(0, 0)] and m.second == [] and m.unmatched_m == [1]  # 5 away: beyond d_maxdist
    back = unbalanced_match(Pm, np.tile(-D, (2, 1)), Pn, D, d_maxdist=2.0)  # directions away: > 90 degrees
    assert back.first == [] and hungarian(np.full((2, 2), np.inf)) == []


def test_matching_bad_input():
    P, D = np.zeros((2, 3)), np.tile([0, 0, 1.0], (2, 1))
    with pytest.raises(TilingError, match="d_maxdist must be a positive length"):
        unbalanced_match(P, D, P, -D, d_maxdist=0.0)
    with pytest.raises(TilingError, match="body has none"):
        unbalanced_match(P, D, np.zeros((0, 3)), np.zeros((0, 3)), 1.0, names=("wing", "body"))
    with pytest.raises(TilingError, match="NaN"):
        unbalanced_match(P, D, P + [0, 0, 1], -D, 1.0, w_angle=float("nan"))


def test_the_sides_may_come_in_either_order():
    rng = np.random.default_rng(5)
    Pm, Dm, Pn, Dn = _instance(rng, 5, 3)
    a = unbalanced_match(Pm, Dm, Pn, Dn, d_maxdist=2.5)
    b = unbalanced_match(Pn, Dn, Pm, Dm, d_maxdist=2.5)  # the smaller side first
    assert sorted(b.first) == sorted((j, i) for i, j in a.first)
    assert sorted(b.second) == sorted((j, i) for i, j in a.second)
    assert b.two_to_one == a.two_to_one and b.unmatched_m == a.unmatched_n and b.unmatched_n == a.unmatched_m
