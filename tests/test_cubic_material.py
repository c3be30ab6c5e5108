"""Materials of cubic symmetry (iga.CubicMaterial) and the lattice's macro model they make (iga.stiffness_table):
closed-form stresses, the isotropic limit against the compiled isotropic kernel, the lattice against its macro
model where homogenisation is exact, sensitivities by the channel against central differences, a design at a
kept solid fraction, and the refusals."""

import meshio
import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from iga import CubicMaterial, ElasticityProblem, ProblemError, optimize, stiffness_table, write_vtu
from iga.elasticity import volume as elastic_volume
from iga.outputs import Compliance, VonMisesNorm
from tiling import library

C11, C12, C44 = 250e9, 120e9, 70e9  # Pa: a cubic crystal's constants (kappa = C11 - C12 - 2 C44 = -80 GPa)


def _sliding_box(material, strain=1e-3, degree_elevation=1):
    """The unit cube stretched by ``strain`` along x, its other faces free to slide on their planes."""
    p = ElasticityProblem(pr.box(), material=material, degree_elevation=degree_elevation)
    return (p.dirichlet("umin", 0.0, components="x").dirichlet("umax", strain, components="x")
            .dirichlet("vmin", 0.0, components="y").dirichlet("wmin", 0.0, components="z"))


def test_a_cubic_crystal_stretched_along_an_axis_is_in_uniaxial_stress_of_its_directional_modulus():
    s = _sliding_box(CubicMaterial((C11, C12, C44))).solve(solver="direct")
    rng = np.random.default_rng(0)
    x = rng.random((20, 3))
    sig = s.stress(x)
    E100 = (C11 - C12) * (C11 + 2 * C12) / (C11 + C12)  # Young's modulus along <100>
    assert np.allclose(sig[:, 0, 0], E100 * 1e-3, rtol=1e-10)
    others = np.abs(sig).reshape(-1, 9)[:, 1:]
    assert others.max() < 1e-9 * E100 * 1e-3
    eps = s.strain(x)  # the lateral contraction: nu_100 = C12 / (C11 + C12)
    assert np.allclose(eps[:, 1, 1], -C12 / (C11 + C12) * 1e-3, rtol=1e-10)
    balance = s.work_balance()
    assert balance.relative_error < 1e-10  # the strain energy includes the cubic term


def test_a_cubic_crystal_heated_between_sliding_walls_has_its_thermal_stress():
    """A uniform rise dT with every face held in its normal direction: no strain, so sigma = -(C11 + 2 C12) alpha
    dT I (a cubic material expands isotropically); held against rigid motion alone it expands free of stress."""
    held = ElasticityProblem(pr.box(), material=CubicMaterial((C11, C12, C44)), degree_elevation=1)
    for face, comp in (("umin", "x"), ("umax", "x"), ("vmin", "y"), ("vmax", "y"), ("wmin", "z"), ("wmax", "z")):
        held = held.dirichlet(face, 0.0, components=comp)
    s = held.thermal(50.0, 1.2e-5).solve(solver="direct")
    x = np.random.default_rng(2).random((10, 3))
    assert np.allclose(s.stress(x), -(C11 + 2 * C12) * 1.2e-5 * 50.0 * np.eye(3), rtol=1e-10, atol=1e-3)
    assert s.work_balance().relative_error < 1e-10
    free = ElasticityProblem(pr.box(), material=CubicMaterial((C11, C12, C44)), degree_elevation=1).hold_rigid()
    s = free.thermal(50.0, 1.2e-5).solve(solver="direct")
    assert np.abs(s.stress(x)).max() < 1e-6 * (C11 + 2 * C12) * 1.2e-5 * 50.0
    assert np.allclose(s.strain(x), 1.2e-5 * 50.0 * np.eye(3), rtol=1e-10, atol=1e-16)


def test_an_affine_displacement_gives_the_cubic_stress_law_at_random_points():
    """Every face held at u = G x (G a random gradient): the exact solution is that field, its stress C : sym(G)
    in Voigt form with C11, C12 and C44, at random points of a curved patch."""
    rng = np.random.default_rng(1)
    G = rng.standard_normal((3, 3)) * 1e-3
    D = pr.twisted(pr.box((1.0, 0.5, 0.4), degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.25))
    p = ElasticityProblem(D, material=CubicMaterial((C11, C12, C44)), degree_elevation=1)
    for face in ("umin", "umax", "vmin", "vmax", "wmin", "wmax"):
        p = p.dirichlet(face, lambda x: x @ G.T)
    s = p.solve(solver="direct", tol=1e-13)
    e = 0.5 * (G + G.T)
    voigt = np.array([[C11, C12, C12], [C12, C11, C12], [C12, C12, C11]]) @ np.diag(e)
    expected = np.diag(voigt) + 2 * C44 * (e - np.diag(np.diag(e)))
    pts = D.evaluate(rng.random((15, 3)))
    assert np.allclose(s.stress(pts), expected, rtol=0, atol=1e-8 * np.abs(expected).max())


def test_a_cubic_material_without_anisotropy_assembles_the_isotropic_stiffness_of_the_compiled_kernel():
    """kappa = 0 (C11 = C12 + 2 C44): the cubic path (the form kernel with a third coefficient) equals the
    isotropic one (the compiled elastic kernel) on a lattice large enough to use it."""
    ms = tiling.regular(pr.box((2.0, 1.0, 1.0)), library.cross(0.4), (4, 2, 2))
    lam, mu = 80e9, 60e9
    iso = ElasticityProblem(ms, youngs=mu * (3 * lam + 2 * mu) / (lam + mu), poisson=lam / (2 * (lam + mu)),
                            degree_elevation=1)
    cub = ElasticityProblem(ms, material=CubicMaterial((lam + 2 * mu, lam, mu)), degree_elevation=1)
    A = elastic_volume.ElasticVolume(iso.disc).assemble(iso.material)[0]
    B = elastic_volume.ElasticVolume(cub.disc).assemble(cub.material)[0]
    assert abs(A - B).max() < 1e-10 * abs(A).max()


@pytest.fixture(scope="module")
def crosses():
    """The cross family's cubic constants (E = 1 GPa, nu = 0.3) over its arm width."""
    return stiffness_table(library.cross, np.linspace(0.2, 0.6, 6), 1e9, 0.3)


def test_the_stiffness_table_holds_the_cells_cubic_constants_and_solid_fractions(crosses):
    from iga import effective_stiffness

    C = effective_stiffness(library.cross(0.44), 1e9, 0.3)
    assert crosses.cubic_error < 1e-9
    a = crosses.values
    assert np.allclose(crosses.fractions, 3 * a**2 - 2 * a**3, rtol=1e-12)  # the cross's volume, exactly
    got = crosses.constants_at([0.44])[0]
    # between the table's values: its cubic spline against the cell's own constants (a few 1e-3 at 0.08 steps)
    assert got == pytest.approx([C[0, 0], C[0, 1], C[3, 3]], rel=1e-2)
    p, h = np.array([0.31, 0.47]), 1e-6
    assert np.allclose(crosses.slopes(p), (crosses.constants_at(p + h) - crosses.constants_at(p - h)) / (2 * h),
                       rtol=1e-6)
    assert np.allclose(crosses.fraction_slope(p), (crosses.fraction(p + h) - crosses.fraction(p - h)) / (2 * h),
                       rtol=1e-6)


def test_the_lattice_stretched_on_sliding_supports_carries_what_its_macro_model_says(crosses):
    """Mirror-symmetric cells under a normal macroscopic strain: the periodic cell solution satisfies the sliding
    supports on every cell wall, so the lattice's reaction equals C11 of the table's own values x strain x area
    to the solver's precision (the same spaces as the cell problems)."""
    arm = float(crosses.values[2])
    ms = tiling.regular(pr.box((2.0, 1.0, 1.0)), library.cross(arm), (2, 1, 1))
    p = ElasticityProblem(ms, youngs=1e9, poisson=0.3, degree_elevation=1)
    for face, comp in (("vmin", "y"), ("vmax", "y"), ("wmin", "z"), ("wmax", "z")):
        p = p.dirichlet(face, 0.0, components=comp)
    s = p.dirichlet("umin", 0.0, components="x").dirichlet("umax", 2e-3, components="x").solve(solver="direct")
    C11_lattice = s.reaction("umax")[0] / 1e-3  # area 1, strain 1e-3
    assert C11_lattice == pytest.approx(crosses.constants[2, 0], rel=1e-8)


def _macro(t, table, **kw):
    """A cantilever macro model (4 x 1 x 1, clamped at x = 0, pulled down at x = 4) whose cubic material is the
    table at the channel t (control values (6, 3, 3) on the refined map)."""
    D = pr.box((4.0, 1.0, 1.0), degrees=(2, 2, 2)).refine(2, [0])[0]
    return (ElasticityProblem(D.with_channel("t", t), material=table.material("t"), **kw).dirichlet("umin", 0.0)
            .traction("umax", [0.0, 0.0, -1e5]))


def test_the_macro_model_s_gradients_by_the_parameter_channel_are_their_finite_differences(crosses):
    rng = np.random.default_rng(3)
    t0 = 0.3 + 0.2 * rng.random((6, 3, 3))
    d = rng.standard_normal(t0.shape) * 1e-4
    for out in (Compliance(), VonMisesNorm(4)):
        s = _macro(t0, crosses).solve(solver="direct", tol=1e-13)
        g = s.gradient(out, wrt="channel:t")
        assert g.shape == t0.shape
        fd = (out.value(_macro(t0 + d, crosses).solve(solver="direct", tol=1e-13))
              - out.value(_macro(t0 - d, crosses).solve(solver="direct", tol=1e-13))) / 2
        assert float(np.sum(g * d)) == pytest.approx(fd, rel=1e-6)
        if isinstance(out, Compliance):
            assert np.all(g < 0)  # thicker arms anywhere: stiffer


def test_the_macro_model_s_shape_and_parameter_gradients_are_their_finite_differences(crosses):
    """A cubic material's shape terms: the macro beam's control points moved (wrt="map"; the table's channel moves
    with the points), and a field-graded lattice of crosses whose material is the table at a channel of the map
    (wrt="parameters": a moved point reads the channel elsewhere, the drag term by C'), against central
    differences of fresh solves."""
    from geometry import SplineFunction
    from geometry import knots as kn
    from iga.adjoint import shape_map
    from iga.design import redesigned
    from iga.shape_design import moved_map

    rng = np.random.default_rng(8)
    base = _macro(0.3 + 0.2 * rng.random((6, 3, 3)), crosses)
    s = base.solve(solver="direct", tol=1e-13)
    D, placed = shape_map(base)
    P0 = np.array(D.control_points)[..., :3]
    dP = rng.standard_normal(P0.shape) * 1e-6
    for out in (Compliance(), VonMisesNorm(4)):
        g = s.gradient(out, wrt="map")

        def at(P, out=out):
            return out.value(base.on(redesigned(base.model, D, moved_map(D, P), placed)).solve(solver="direct",
                                                                                               tol=1e-13))

        fd = (at(P0 + dP) - at(P0 - dP)) / 2
        assert float(np.sum(g * dP)) == pytest.approx(fd, rel=1e-6)
    U = kn.uniform_knots(2, 1)
    box = pr.box((0.02, 0.01, 0.01), degrees=(2, 2, 2))
    box = box.with_channel("t", 0.3 + 0.2 * rng.random(box.control_points.shape[:3]))

    def lattice(c):
        ms = tiling.field_graded(box, library.face_graded_cross, (2, 1, 1), SplineFunction((2, 2, 2), [U, U, U], c))
        return (ElasticityProblem(ms, material=crosses.material("t")).dirichlet("umin", 0.0)
                .traction("umax", [0.0, 0.0, -1e4]).solve(solver="direct", tol=1e-13))

    c0 = 0.3 + 0.1 * rng.random((3, 3, 3, 1))
    d = rng.standard_normal(c0.shape) * 1e-5
    g = lattice(c0).gradient(Compliance(), wrt="parameters")
    fd = (Compliance().value(lattice(c0 + d)) - Compliance().value(lattice(c0 - d))) / 2
    assert float(np.sum(g.reshape(c0.shape) * d)) == pytest.approx(fd, rel=1e-6)


def test_the_poisson_ratio_channel_s_compliance_gradient_is_its_finite_difference():
    rng = np.random.default_rng(4)
    D = pr.box((3.0, 1.0, 1.0), degrees=(2, 2, 2)).refine(1, [0])[0]
    nu0 = 0.2 + 0.1 * rng.random(D.control_points.shape[:3])

    def solved(nu):
        return (ElasticityProblem(D.with_channel("nu", nu), youngs=1e9, poisson="nu", degree_elevation=1)
                .dirichlet("umin", 0.0).traction("umax", [0.0, 1e4, -1e4]).solve(solver="direct", tol=1e-13))

    g = solved(nu0).gradient(Compliance(), wrt="channel:nu")
    d = rng.standard_normal(nu0.shape) * 1e-5
    fd = (Compliance().value(solved(nu0 + d)) - Compliance().value(solved(nu0 - d))) / 2
    assert float(np.sum(g * d)) == pytest.approx(fd, rel=1e-6)


def test_a_macro_cantilever_designed_at_a_kept_solid_fraction_is_stiffer(crosses):
    t0 = np.full((6, 3, 3), 0.4)
    p = _macro(t0, crosses, degree_elevation=0)
    res = optimize(p, Compliance(), wrt="channel:t", bounds=(0.2, 0.6), keep_fraction=True, maxiter=15)
    assert res.objective < 0.85 * res.initial  # thicker where the bending moment is large
    assert len(res.history) >= 2
    for step in res.history:  # the solid fraction (in DesignStep.mean) kept at the uniform design's, as far as
        # SLSQP's linearised equality keeps a curved constraint at its iterates (measured: 3e-4 at most)
        assert step.mean == pytest.approx(float(crosses.fraction([0.4])[0]), rel=3e-3)
    assert res.values.min() >= 0.2 - 1e-12 and res.values.max() <= 0.6 + 1e-12
    # more material at the clamped end than at the loaded one
    assert res.values[0].mean() > res.values[-1].mean()


def test_the_vtu_of_a_cubic_solution_carries_its_constants(crosses, tmp_path):
    s = _macro(np.full((6, 3, 3), 0.35), crosses).solve(solver="direct")
    m = meshio.read(str(write_vtu(tmp_path / "macro.vtu", s)))
    c = m.point_data["cubic_constants"]
    assert c.shape[1] == 3
    assert np.allclose(c, crosses.constants_at([0.35]), rtol=1e-8)
    assert np.all(np.isfinite(m.point_data["von_mises"]))


def test_cubic_materials_refuse_bad_input(crosses):
    with pytest.raises(ProblemError, match="positive definite"):
        CubicMaterial((100e9, 120e9, 50e9))  # C11 < C12
    with pytest.raises(ProblemError, match="positive definite"):
        CubicMaterial((100e9, 20e9, -1.0))
    with pytest.raises(ProblemError, match="three numbers"):
        CubicMaterial("steel")
    with pytest.raises(ProblemError, match="channel it reads"):
        CubicMaterial(crosses.material("t").table)
    with pytest.raises(ProblemError, match="not both"):
        ElasticityProblem(pr.box(), youngs=1e9, poisson=0.3, material=CubicMaterial((C11, C12, C44)))
    with pytest.raises(ProblemError, match="youngs= and poisson="):
        ElasticityProblem(pr.box(), youngs=1e9)
    with pytest.raises(ProblemError, match="not a channel|channel"):
        ElasticityProblem(pr.box(), material=crosses.material("t"))  # the map has no channel t
    with pytest.raises(ProblemError, match="outside the stiffness table"):
        _macro(np.full((6, 3, 3), 0.7), crosses).solve(solver="direct")
    with pytest.raises(ProblemError, match="cubic symmetry"):
        stiffness_table(lambda a: library.face_graded_cross(umin=a, umax=a), [0.2, 0.4], 1e9, 0.3)
    with pytest.raises(ProblemError, match="keep_fraction needs"):
        D = pr.box((4.0, 1.0, 1.0), degrees=(2, 2, 2))
        p = ElasticityProblem(D.with_channel("E", np.full((3, 3, 3), 1e9)), youngs="E", poisson=0.3)
        optimize(p.dirichlet("umin", 0.0).traction("umax", [0, 0, -1.0]), Compliance(), wrt="channel:E",
                 bounds=(1e8, 2e9), keep_fraction=True)


MACRO = """
[map]
primitive = "box"
args = {size = [0.08, 0.02, 0.02], degrees = [2, 2, 2], elements = [4, 1, 1], channels = {t = 0.35}}

[tile]
library = "cube"

[paving]
scheme = "regular"
counts = [1, 1, 1]

[physics]
kind = "elasticity"
youngs = 7e10
poisson = 0.33
macro = {family = "cross", values = [0.15, 0.3, 0.45, 0.6], channel = "t"}

[[support]]
tag = "umin"

[[load]]
kind = "traction"
tag = "umax"
value = [0.0, 0.0, -1e4]

[design]
variables = "channel:t"
objective = "compliance"
bounds = [0.15, 0.6]
keep_fraction = true
iterations = 8

[solver]
degree_elevation = 1

[output]
dir = "out"
name = "macro"
"""


@pytest.mark.slow
def test_a_pipeline_designs_a_macro_model_at_its_solid_fraction(tmp_path):
    """physics.macro: the map alone with the cross's cubic stiffness at the channel t, designed by design
    keep_fraction; the stress VTU carries the constants of the final design, read back by meshio."""
    import json
    import tomllib

    from iga.app.pipeline import run_pipeline

    cfg = tomllib.loads(MACRO)
    cfg["output"]["dir"] = str(tmp_path / "out")
    summary = run_pipeline(cfg, tmp_path)
    d = summary["elasticity"]["design"]
    assert d["final"] < 0.85 * d["initial"]
    table = stiffness_table(library.cross, [0.15, 0.3, 0.45, 0.6], 7e10, 0.33)
    assert d["steps"][-1]["mean"] == pytest.approx(float(table.fraction([0.35])[0]), rel=3e-3)
    m = meshio.read(tmp_path / "out" / "macro_stress.vtu")
    c = m.point_data["cubic_constants"]
    assert np.all(c[:, 2] > 0) and np.ptp(c[:, 0]) > 0.1 * c[:, 0].max()  # graded: C11 varies along the beam
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["elasticity"]["design"]["final"] == d["final"]


@pytest.mark.parametrize("change, match", [
    ({"physics": {"kind": "thermo-elastic", "expansion": 2.3e-5,
                  "macro": {"family": "cross", "values": [0.2, 0.4], "channel": "t"}}},
     "physics.macro: applies to physics.kind = 'elasticity'"),
    ({"tile": {"library": "cross"}}, "physics.macro: analyses the map as a continuum"),
    ({"physics": {"macro": {"family": "hollow", "values": [0.2, 0.4], "channel": "t"}}}, "physics.macro.family"),
    ({"physics": {"macro": {"family": "cross", "values": [0.4, 0.2], "channel": "t"}}}, "physics.macro.values"),
    ({"physics": {"macro": {"family": "cross", "values": [0.2, 0.4]}}}, r"physics\.macro\.'channel'"),
    ({"design": {"mean": 0.35}}, "design.mean: and design.keep_fraction"),
    ({"design": {"variables": "map", "move": 0.001, "keep_fraction": True}}, "design.keep_fraction"),
])
def test_a_bad_macro_pipeline_is_refused_naming_the_key(change, match):
    import copy
    import tomllib

    from iga.app.config import validate

    cfg = tomllib.loads(MACRO)
    for section, values in change.items():
        merged = copy.deepcopy(cfg.get(section, {}))
        merged.update(values)
        if section == "design" and values.get("variables") == "map":
            merged = {k: v for k, v in merged.items() if k not in ("bounds",)}
        cfg[section] = merged
    with pytest.raises(ProblemError, match=match):
        validate(cfg)
