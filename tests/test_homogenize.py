"""Effective conductivity of periodic tiles: laminates, cubic symmetry, the full lattice, refusals."""

import numpy as np
import pytest
from commands import iga_command

import tiling
from geometry import primitives as pr
from iga import HeatProblem
from iga.errors import ProblemError
from iga import effective_conductivity, effective_stiffness
from tiling import library as L
from tiling.tile import Tile


def test_a_laminate_has_the_arithmetic_mean_along_and_the_harmonic_mean_across_its_layers():
    k1, k2 = 1.0, 9.0
    for axis in range(3):
        elements = [1, 1, 1]
        elements[axis] = 2  # a knot on the layers' interface: the piecewise linear corrector is in the space
        tile = Tile([pr.box(degrees=(1, 1, 1), elements=tuple(elements))], name="laminate")
        e = effective_conductivity(tile, lambda x, a=axis: np.where(x[:, a] < 0.5, k1, k2), degree_elevation=0,
                                   diagnostics=True)
        want = np.full(3, 0.5 * (k1 + k2))
        want[axis] = 2 * k1 * k2 / (k1 + k2)
        assert np.abs(e.tensor - np.diag(want)).max() < 1e-10 * k2
        assert e.volume_fraction == pytest.approx(1.0) and e.periodic_faces == 3


def test_the_cross_tile_is_cubic_inside_the_bounds_and_converges_in_refinement():
    e = [effective_conductivity(L.cross(), 2.0, refine=r, diagnostics=True) for r in (0, 1, 2)]
    for x in e:
        K = x.tensor
        assert np.abs(K - K[0, 0] * np.eye(3)).max() < 1e-10 * K[0, 0]  # cubic symmetry: K = k_eff I
        phi = x.volume_fraction
        assert 0 < K[0, 0] < 2.0 * 2 * phi / (3 - phi)  # below the Hashin-Shtrikman upper bound (voids)
        assert x.symmetry_error < 1e-12
    d = [abs(e[i + 1].tensor[0, 0] - e[i].tensor[0, 0]) for i in range(2)]
    assert d[1] < 0.6 * d[0]  # differences per refinement shrink (measured 1.3e-3, 6.8e-4 of 0.21)


@pytest.mark.parametrize("n", [2, 4])
def test_a_full_lattice_between_two_plates_conducts_as_the_cell_problem_says(n):
    # the cross is mirror symmetric, so the plates sit where the periodic corrector is constant: no boundary
    # layer, the apparent conductivity of the whole lattice is the effective one for every n
    k_eff = effective_conductivity(L.cross(), 1.0)[0, 0]  # the (3, 3) array of the design contract
    ms = tiling.regular(pr.box(), L.cross(), (n, n, n))
    s = HeatProblem(ms, conductivity=1.0, degree_elevation=1).dirichlet("umin", 1.0).dirichlet("umax", 0.0).solve()
    assert s.flux("umax") == pytest.approx(k_eff, rel=1e-9)


def test_tiles_that_cannot_be_homogenised_are_refused_naming_why():
    with pytest.raises(ProblemError, match="has no trivariate patches: a surface tile has no volume"):
        effective_conductivity(L.hollow_cross())
    lopsided = Tile([pr.box((1.0, 0.5, 1.0), degrees=(1, 1, 1))], name="half")  # the wall y = 1 is not reached
    with pytest.raises(ProblemError, match=r"not periodic along y") as info:
        effective_conductivity(lopsided)
    assert "unit cell" not in str(info.value)  # inside the cell: no hint about its extent
    with pytest.raises(ProblemError, match=r"not periodic along x.*its control points span x in \[0, 2\]"):
        effective_conductivity(pr.box((2.0, 1.0, 1.0), degrees=(1, 1, 1)))
    with pytest.raises(ProblemError, match=r"cannot homogenise a str: pass a tile"):
        effective_conductivity("cross")


def test_bare_trivariates_in_the_unit_cell_are_a_tile():

    solid = pr.box(degrees=(2, 2, 2), elements=(2, 1, 1))
    assert np.abs(effective_conductivity(solid, 3.0) - 3.0 * np.eye(3)).max() < 1e-12
    # two boxes side by side, as a list: the laminate of their conductivities (arithmetic along, harmonic across)
    half = pr.box((0.5, 1.0, 1.0), degrees=(1, 1, 1))
    halves = [half, half.translate([0.5, 0, 0])]
    K = effective_conductivity(halves, lambda x: np.where(x[:, 0] < 0.5, 1.0, 4.0), degree_elevation=0)
    assert np.allclose(np.diag(K), [2 / (1 + 1 / 4), 2.5, 2.5], rtol=1e-12)
    assert np.abs(K - np.diag(np.diag(K))).max() < 1e-12
    E, nu = 2.0, 0.3
    C = effective_stiffness(solid, E, nu)
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    assert np.allclose(np.diag(C), [lam + 2 * mu] * 3 + [mu] * 3, rtol=1e-12) and np.isclose(C[0, 1], lam, rtol=1e-12)


def _laminate_stiffness(E1, E2, nu):
    """Exact effective stiffness of a 50/50 laminate of isotropic layers normal to x (Voigt, engineering)."""
    lam = lambda E: E * nu / ((1 + nu) * (1 - 2 * nu))  # noqa: E731
    mu = lambda E: E / (2 * (1 + nu))  # noqa: E731
    avg = lambda f: 0.5 * (f(E1) + f(E2))  # noqa: E731
    P = lambda E: lam(E) + 2 * mu(E)  # noqa: E731
    inv = avg(lambda E: 1 / P(E))
    r = avg(lambda E: lam(E) / P(E))
    C = np.zeros((6, 6))
    C[0, 0] = 1 / inv
    C[0, 1] = C[0, 2] = C[1, 0] = C[2, 0] = r / inv
    C[1, 1] = C[2, 2] = avg(lambda E: P(E) - lam(E) ** 2 / P(E)) + r * r / inv
    C[1, 2] = C[2, 1] = avg(lambda E: lam(E) - lam(E) ** 2 / P(E)) + r * r / inv
    C[3, 3] = avg(mu)  # shear in the layers' plane: strain continuous
    C[4, 4] = C[5, 5] = 1 / avg(lambda E: 1 / mu(E))  # shear across the layers: stress continuous
    return C


def test_effective_stiffness_of_a_solid_a_laminate_and_the_cubic_cross():
    from iga import effective_stiffness

    E, nu = 200.0, 0.3
    lam, mu = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    solid = effective_stiffness(Tile([pr.box(degrees=(1, 1, 1))], name="solid"), E, nu)
    assert isinstance(solid, np.ndarray) and solid.shape == (6, 6)
    want = np.diag([lam + 2 * mu] * 3 + [mu] * 3)
    want[:3, :3] += lam * (1 - np.eye(3))
    assert np.abs(solid - want).max() < 1e-10 * E
    layers = Tile([pr.box(degrees=(1, 1, 1), elements=(2, 1, 1))], name="laminate")
    got = effective_stiffness(layers, lambda x: np.where(x[:, 0] < 0.5, 1.0, 10.0), 0.25, degree_elevation=0,
                              diagnostics=True)
    assert np.abs(got.tensor - _laminate_stiffness(1.0, 10.0, 0.25)).max() < 1e-10 * 10.0
    C = effective_stiffness(L.cross(), 1.0, 0.3)
    assert np.allclose(np.diag(C)[:3], C[0, 0], rtol=1e-10) and np.allclose(np.diag(C)[3:], C[3, 3], rtol=1e-10)
    assert np.allclose([C[0, 1], C[0, 2], C[1, 2]], C[0, 1], rtol=1e-10) and np.abs(C[:3, 3:]).max() < 1e-12
    assert 0 < C[3, 3] < C[0, 0] < 0.216 * (lam + 2 * mu) / E  # below the Voigt bound of the solid fraction


@pytest.mark.slow
def test_the_homogenize_command_prints_the_tensors_and_names_bad_arguments():
    out = iga_command("homogenize", "--tile", "cross", "--arg", "arm=0.4", "--youngs", "1e9")
    assert out.returncode == 0, out.stderr
    k = effective_conductivity(L.cross(0.4))[0, 0]
    assert "volume fraction 0.352" in out.stdout and f"{k:.6f}" in out.stdout and "effective stiffness" in out.stdout
    C = effective_stiffness(L.cross(0.4), 1e9, 0.3)  # the cross is cubic: its three constants and Zener's ratio
    assert f"C11 = {C[0, 0]:.6g}" in out.stdout and f"C44 = {C[3, 3]:.6g}" in out.stdout
    assert f"Zener ratio 2 C44 / (C11 - C12) = {2 * C[3, 3] / (C[0, 0] - C[0, 1]):.4g}" in out.stdout
    skew = iga_command("homogenize", "--tile", "bent_cross", "--youngs", "1e9")  # bowed arms: not cubic
    assert skew.returncode == 0, skew.stderr
    assert "effective stiffness" in skew.stdout and "cubic symmetry" not in skew.stdout
    bad = iga_command("homogenize", "--tile", "cross", "--arg", "width=0.4")
    assert bad.returncode == 1 and "does not take ['width']" in bad.stderr and "Traceback" not in bad.stderr


@pytest.mark.slow
def test_the_cell_fields_are_written_and_average_to_the_effective_flux(tmp_path):
    """The cell fields as VTU (the correctors and the cell's heat flux for unit macroscopic gradients): in a
    laminate across x the flux for a gradient along x is one constant, -K_xx, at every written point; in the cross
    tile the flux averages over the cell to -K e_x (the sampled linear cells: to 1%)."""
    import pyvista as pv

    tile = Tile([pr.box(degrees=(1, 1, 1), elements=(2, 1, 1))], name="laminate")
    e = effective_conductivity(tile, lambda x: np.where(x[:, 0] < 0.5, 1.0, 9.0), degree_elevation=0, diagnostics=True)
    g = pv.read(e.write_vtu(tmp_path / "laminate.vtu"))
    assert np.abs(g.point_data["cell_flux_x"][:, 0] + e.tensor[0, 0]).max() < 1e-10
    assert np.isfinite(e.condition) and e.condition >= 1
    cross = effective_conductivity(L.cross(0.3), diagnostics=True)
    g = pv.read(cross.write_vtu(tmp_path / "cross.vtu", samples=4))
    mean = g.integrate_data().point_data["cell_flux_x"][0]
    import meshio  # a second reader: the same points and fields

    m = meshio.read(tmp_path / "cross.vtu")
    assert np.array_equal(m.points, g.points) and np.allclose(m.point_data["corrector"], g.point_data["corrector"])
    assert mean == pytest.approx(-cross.tensor[:, 0], abs=1e-2 * cross.tensor[0, 0])
    out = iga_command("homogenize", "--tile", "cross", "--out", tmp_path / "c.vtu")
    assert out.returncode == 0 and "cell fields" in out.stdout and (tmp_path / "c.vtu").stat().st_size > 0
    bad = iga_command("homogenize", "--tile", "cross", "--out", tmp_path / "c.txt")
    assert bad.returncode == 1 and "ending in .vtu" in bad.stderr


@pytest.mark.slow
def test_a_tile_without_mirror_symmetry_shows_an_o_1_over_n_boundary_layer():
    """Scale separation: the bent cross (bowed arms) between two plates conducts K_eff (1 + c / n): the
    difference halves with every doubling of n (the mirror-symmetric cross has none: c = 0)."""
    tile = L.bent_cross()
    k = effective_conductivity(tile)[2, 2]
    diff = []
    for n in (1, 2, 4):
        ms = tiling.regular(pr.box(), tile, (n, n, n))
        q = HeatProblem(ms, 1.0, degree_elevation=1).dirichlet("wmin", 1.0).dirichlet("wmax", 0.0).solve()
        diff.append(-q.flux("wmin") / k - 1)
    assert diff[0] > 0 and diff[1] / diff[0] == pytest.approx(0.5, abs=0.02) and diff[2] / diff[1] == pytest.approx(
        0.5, abs=0.02)
