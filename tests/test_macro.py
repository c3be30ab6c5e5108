"""Graded lattices and their macro models: a tile family graded along w (tiling.graded), the
effective tensors tabulated over its parameter (iga.effective_table) and written into conductivity channels of
the map (iga.macro_map); the macro model against the full lattice."""

import numpy as np
import pytest

from geometry import MultiPatch, primitives as pr
from geometry.patches.multipatch import detect_interfaces
from iga import HeatProblem, ProblemError, effective_conductivity, effective_table, macro_map
from tiling import TilingError, graded, library as L
from tiling.materials import graded_channel


@pytest.fixture(scope="module")
def table():
    return effective_table(L.cross, np.linspace(0.15, 0.45, 7))


def test_the_table_interpolates_the_cell_problems(table):
    assert table.tensors.shape == (7, 3, 3) and np.all(np.diff(table.tensors[:, 0, 0]) > 0)  # thicker arms conduct
    for K in table.tensors:  # the cross is cubic: K = k_eff I
        assert np.abs(K - K[0, 0] * np.eye(3)).max() < 1e-10 * K[0, 0]
    for p in (0.275, 0.41):  # between the table's points: the cubic spline against the cell problem itself
        direct = effective_conductivity(L.cross(p))[0, 0]
        assert table.tensor([p])[0, 0, 0] == pytest.approx(direct, rel=1e-4)
    with pytest.raises(ProblemError, match=r"parameter 0.5 lies outside the table of cross \(\[0.15, 0.45\]\)"):
        table.tensor([0.3, 0.5])
    with pytest.raises(ProblemError, match="two increasing"):
        effective_table(L.cross, [0.3, 0.2])


def test_a_graded_paving_conforms_between_its_layers():
    """Layers of graded crosses meet face to face (their shared faces have one width): the interfaces by
    construction equal the geometric search, and an affine temperature is reproduced exactly."""
    D = pr.box((1.0, 1.0, 2.0))
    ms = graded(D, L.graded_cross, (2, 2, 4), lambda s: 0.2 + 0.2 * s)
    assert ms.info["parameter"] == pytest.approx([0.2, 0.25, 0.3, 0.35, 0.4])
    found, bad = detect_interfaces(ms.patches)
    assert not bad and len(found) == len(ms.interfaces) > 0
    T = lambda x: 1.0 + 2.0 * x[:, 0] - x[:, 1] + 0.5 * x[:, 2]  # noqa: E731
    sol = HeatProblem(ms, 3.0).dirichlet("boundary", T).solve(tol=1e-12)
    assert sol.l2_error(T) < 1e-9 and sol.info["components"]["count"] == 1
    with pytest.raises(TilingError, match=r"graded: layer 0 \(parameter 0 to 0.25\): graded_cross: the bottom arm"):
        graded(D, L.graded_cross, (1, 1, 4), lambda s: s)
    with pytest.raises(TilingError, match="not a channel of the map"):
        graded(D, L.graded_cross, (1, 1, 4), "arm")
    with pytest.raises(TilingError, match="family must be a callable"):
        graded(D, "cross", (1, 1, 4), "arm")


def test_the_macro_model_of_a_graded_lattice_in_a_curved_map_matches_the_lattice(table):
    """Arms 0.2 -> 0.4 along w in an annulus sector (curved, rational), held at 1 and 0 on its w faces: the heat
    flow of the macro model (the map alone, its conductivity from the table) within 2% of the full lattice's
    (measured: 5e-4; benchmarks/homogenization.py times both)."""
    D = graded_channel(pr.annulus(1.0, 1.3, 0.6, angle=0.4), "arm", 0.2, 0.4, "wmin")
    full = HeatProblem(graded(D, L.graded_cross, (3, 2, 4), "arm"), 1.0, degree_elevation=1)
    q_full = full.dirichlet("wmin", 1.0).dirichlet("wmax", 0.0).solve().flux("wmin")
    Dm, names = macro_map(D, table, "arm")
    assert len(names) == 6 and set(names) <= set(Dm.channels) and Dm.breakpoints(2).size - 1 >= 8
    macro = HeatProblem(Dm, conductivity=names, degree_elevation=1).dirichlet("wmin", 1.0).dirichlet("wmax", 0.0)
    q_macro = macro.solve().flux("wmin")
    assert q_macro == pytest.approx(q_full, rel=0.02)
    assert x_inside(Dm, D)  # the refined map is the same map
    with pytest.raises(ProblemError, match="'density' is not a channel of the map"):
        macro_map(D, table, "density")
    wide = graded_channel(pr.box(), "arm", 0.1, 0.4, "wmin")
    with pytest.raises(ProblemError, match="outside the table"):
        macro_map(wide, table, "arm")


def x_inside(a, b) -> bool:
    x = np.random.default_rng(0).random((200, 3))
    return bool(np.abs(a.evaluate(x)[:, :3] - b.evaluate(x)[:, :3]).max() < 1e-12)


def test_graded_cross_refuses_widths_outside_the_cell():
    with pytest.raises(TilingError, match="top arm width must be in"):
        L.graded_cross(0.2, 1.2)
    assert len(MultiPatch.from_splines(L.graded_cross(0.3, 0.3).patches).interfaces) == 6  # the plain cross's
