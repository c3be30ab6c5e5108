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


def test_a_field_graded_lattice_conforms_in_all_three_directions_and_solves():
    import tiling

    D = pr.box((0.03, 0.02, 0.02), degrees=(1, 1, 1)).with_channel("rho", np.linspace(0.2, 0.4, 8).reshape(2, 2, 2))
    field = lambda s: 0.15 + 0.1 * s[:, 0] + 0.08 * s[:, 1] + 0.12 * s[:, 2] ** 2  # noqa: E731  (all three ways)
    ms = tiling.field_graded(D, L.face_graded_cross, (3, 2, 2), field)
    plain = tiling.regular(D, L.cross(), (3, 2, 2))
    assert len(ms.interfaces) == len(plain.interfaces) == 12 * 6 + 2 * 2 * 2 + 3 * 1 * 2 + 3 * 2 * 1
    u = ms.info["faces"][0]
    assert u.shape == (4, 2, 2) and np.all(np.diff(u[:, 0, 0]) > 0)  # widths grow along u ...
    assert np.all(np.diff(ms.info["faces"][2][0, 0, :]) > 0)  # ... and along w
    # two neighbours' arms end on the same square: the wall's value read once, by both
    t0, t1 = ms.tiles[0], ms.tiles[4]  # cells (0, 0, 0) and (1, 0, 0)
    assert t0.name.split(", ")[1] == t1.name.split("(")[1].split(",")[0]
    s = HeatProblem(ms, conductivity=10.0).dirichlet("umin", 1.0).dirichlet("umax", 0.0).solve()
    assert abs(s.flux("umin") + s.flux("umax")) < 1e-9 * abs(s.flux("umin"))  # what enters leaves
    assert s.info.balance.relative_error < 1e-10
    from_channel = tiling.field_graded(D, L.face_graded_cross, (3, 2, 2), "rho")
    walls = np.stack(np.meshgrid([0, 1 / 3, 2 / 3, 1], [0.25, 0.75], [0.25, 0.75], indexing="ij"), -1)
    expected = D.evaluate(walls.reshape(-1, 3))[:, 3].reshape(4, 2, 2)  # the channel at the u-walls' centres
    assert np.allclose(from_channel.info["faces"][0], expected, rtol=1e-12)
    uniform = tiling.field_graded(D, L.face_graded_cross, (3, 2, 2), 0.3)
    for P, Q in zip(uniform.patches, plain.patches):  # a constant field is the plain cross lattice
        assert np.allclose(P.spline.control_points, Q.spline.control_points)
    with pytest.raises(TilingError, match=r"cell \(0, 0, 0\).*umin arm width must be in \(0, 1\)"):
        tiling.field_graded(D, L.face_graded_cross, (3, 2, 2), lambda s: 1.5 - s[:, 0])
    with pytest.raises(TilingError, match="not a channel of the map"):
        tiling.field_graded(D, L.face_graded_cross, (3, 2, 2), "k")
    with pytest.raises(TilingError, match="one finite value per face centre"):
        tiling.field_graded(D, L.face_graded_cross, (3, 2, 2), lambda s: np.nan * s[:, 0])
