"""Linear elasticity on the heat analysis's machinery: patch tests on micro-structures, measured rates, Lame's
cylinder, thermal expansion, reactions, and bad input."""

import numpy as np
import pytest

import tiling
from geometry import primitives as pr
from iga import ElasticityProblem, HeatProblem
from iga.errors import ProblemError, SingularProblemError
from tiling import library as L

A = np.array([[1.0, 0.2, -0.3], [0.1, -0.5, 0.4], [0.3, 0.2, 0.7]]) * 1e-3
b = np.array([1e-4, -2e-4, 3e-4])


def affine(x):
    return x @ A.T + b


def _patch_test(model, **kw):
    s = ElasticityProblem(model, youngs=70e9, poisson=0.3, **kw).dirichlet("boundary", affine).solve()
    x = _inside_points(s)
    err = np.abs(s.displacement(x) - affine(x)).max() / np.abs(affine(x)).max()
    stress = s.stress(x)
    lam, mu = 70e9 * 0.3 / (1.3 * 0.4), 70e9 / 2.6
    eps = 0.5 * (A + A.T)
    want = lam * np.trace(eps) * np.eye(3) + 2 * mu * eps
    return err, np.abs(stress - want).max() / np.abs(want).max(), s


def _inside_points(s, n=40):
    """Points of the model: images of random parameters of random patches."""
    rng = np.random.default_rng(5)
    patches = s.problem.model.patches
    idx = rng.integers(0, len(patches), n)
    return np.concatenate([patches[i].image(rng.uniform(0.05, 0.95, (1, 3)))[:, :3] for i in idx])


@pytest.mark.slow
@pytest.mark.parametrize("which", ["hierarchy", "bifurcation", "capped"])
def test_an_affine_displacement_is_reproduced_on_every_kind_of_micro_structure(which):
    box = pr.box((2.0, 1.0, 1.5), degrees=(1, 1, 1))
    if which == "hierarchy":
        model = tiling.hierarchical(box, L.heat_sink_t2(), (1, 1), 3)
    elif which == "bifurcation":
        model = tiling.bifurcation(pr.box((1.0, 1.0, 6.0)), levels=[0, 0, 1, 1, 0, 0], tile="1-4a")
    elif which == "capped":
        model = tiling.regular(box, L.cross(), (2, 1, 1), seal="cap")
    err, serr, s = _patch_test(model)
    assert err < 1e-9 and serr < 1e-7
    assert s.info["work"]["relative_error"] < 1e-9
    glue = s.info["constraints"]
    assert glue["identity_pairs"] + glue["branch_rows"] > 0


@pytest.mark.slow
@pytest.mark.long
def test_an_affine_field_is_reproduced_across_v_rep_union_bridges_with_forks():
    # the union bridges are isoparametric along their length (analysis degree = their Hermite geometry's,
    # tiling.vrep.tubes.tube_space), so an affine field lies in their spaces: the elastic and the heat patch
    # tests hold on the bridges themselves (before, with the faces' degree along them: 9e-4 and 1e-3)
    from iga import HeatProblem
    from tiling.vrep import Primitive, vrep_microstructure

    DA, DB = pr.box((2.0, 1.0, 1.0)), pr.box((2.0, 1.0, 1.0)).translate([1.5, 0.0, 0.0])
    res = vrep_microstructure(Primitive(DA, L.cross(), (4, 2, 2), 2, "A") | Primitive(DB, L.cross(), (6, 3, 3), 1, "B"))
    assert res.bridges.union.forks > 0  # two-to-one bifurcation bridges
    ms = res.microstructure
    bridges = {id(P) for u in res.unions for P in u.patches}
    idx = [i for i, P in enumerate(ms.patches) if id(P) in bridges]
    assert len(idx) >= 3 * res.bridges.union.forks  # a base and two arms per fork
    rng = np.random.default_rng(8)
    params = rng.uniform(0.02, 0.98, (len(idx), 2, 3))
    x = np.concatenate([ms.patches[i].image(q) for i, q in zip(idx, params)])  # points on every bridge
    s = ElasticityProblem(ms, youngs=70e9, poisson=0.3).dirichlet("boundary", affine).solve()
    assert np.abs(s.displacement(x) - affine(x)).max() < 1e-9 * np.abs(affine(x)).max()  # measured 4e-14
    lam, mu = 70e9 * 0.3 / (1.3 * 0.4), 70e9 / 2.6
    eps = 0.5 * (A + A.T)
    want = lam * np.trace(eps) * np.eye(3) + 2 * mu * eps
    assert np.abs(s.stress(x) - want).max() < 1e-7 * np.abs(want).max()  # measured 2e-11
    assert s.info["work"]["relative_error"] < 1e-9
    g = np.array([3.0, -1.0, 2.0])
    h = HeatProblem(ms).dirichlet("boundary", lambda y: 10.0 + y @ g).solve()
    for i, q in zip(idx, params):
        T, grad, y, _ = h.evaluate(i, q)
        assert np.abs(T - 10.0 - y @ g).max() < 1e-9 * 20 and np.abs(grad - g).max() < 1e-7 * 3


def test_reactions_balance_the_applied_traction_on_a_lattice():
    ms = tiling.regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (2, 1, 1))
    t = np.array([1e5, 2e4, -3e4])
    s = (ElasticityProblem(ms, youngs=1e9, poisson=0.25).dirichlet("umin", 0.0).traction("umax", t).solve())
    applied = np.array(s.info["applied_N"]["umax"])
    area = sum(fd.dAw.sum() for fd in s.problem.faces([k for k in ms.tags["umax"]]))
    assert np.allclose(applied, t * area, rtol=1e-12)
    assert np.abs(s.reaction("umin") + applied).max() < 1e-8 * np.abs(applied).max()
    assert s.info["work"]["relative_error"] < 1e-9 and s.strain_energy() > 0


def _manufactured(p):
    """u = (phi, 2 phi, -phi), phi = sin x sin y sin z, constant lambda, mu: f = -mu lap u - (lambda + mu) grad div u."""
    lam, mu = 1.2, 0.8
    c = np.array([1.0, 2.0, -1.0])

    def derivs(x):
        s, co = np.sin(x), np.cos(x)
        phi = s[:, 0] * s[:, 1] * s[:, 2]
        g = np.stack([co[:, 0] * s[:, 1] * s[:, 2], s[:, 0] * co[:, 1] * s[:, 2], s[:, 0] * s[:, 1] * co[:, 2]], 1)
        H = np.empty((len(x), 3, 3))
        for i in range(3):
            for j in range(3):
                f = [s[:, k] for k in range(3)]
                if i == j:
                    f[i] = -s[:, i]
                else:
                    f[i], f[j] = co[:, i], co[:, j]
                H[:, i, j] = f[0] * f[1] * f[2]
        return phi, g, H

    def exact(x):
        return derivs(x)[0][:, None] * c

    def grad(x):
        return c[None, :, None] * derivs(x)[1][:, None, :]

    def force(x):
        phi, g, H = derivs(x)
        lap = np.trace(H, axis1=1, axis2=2)
        return -mu * lap[:, None] * c - (lam + mu) * np.einsum("nij,j->ni", H, c)

    E, nu = mu * (3 * lam + 2 * mu) / (lam + mu), lam / (2 * (lam + mu))
    geo = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(p, p, p)), 0.4, axis_point=(0.5, 0.5))
    errs = []
    for r in (1, 2, 3):
        s = (ElasticityProblem(geo, youngs=E, poisson=nu, refine=r).dirichlet("boundary", exact)
             .body_force(force).solve(solver="direct"))
        errs.append((s.l2_error(exact), s.h1_error(grad)))
    return np.array(errs)


@pytest.mark.parametrize("p", [1, 2, 3])
def test_manufactured_solution_converges_at_the_optimal_rates_on_a_curved_patch(p):
    e = _manufactured(p)
    l2 = np.log2(e[:-1, 0] / e[1:, 0])
    h1 = np.log2(e[:-1, 1] / e[1:, 1])
    assert l2[-1] > p + 1 - 0.3 and h1[-1] > p - 0.3, (l2, h1)


@pytest.mark.slow
@pytest.mark.long
def test_lames_thick_cylinder_under_internal_pressure():
    a, c, p, E, nu = 0.5, 1.0, 1e6, 200e9, 0.3
    # the exact NURBS annulus, quadratic across the wall too (one exact degree elevation of the geometry), then
    # the analysis: degree elevation 1 (cubic in the plane), refine 4 (16 elements each way)
    shell = pr.annulus(a, c, 0.2).elevate(1)
    k = a * a * p / (c * c - a * a)

    def ur(r):  # plane strain
        return (1 + nu) / E * k * ((1 - 2 * nu) * r + c * c / r)

    def exact(x):
        r = np.hypot(x[:, 0], x[:, 1])
        return np.stack([ur(r) * x[:, 0] / r, ur(r) * x[:, 1] / r, 0 * r], 1)

    def grad(x):
        r = np.hypot(x[:, 0], x[:, 1])
        e = np.stack([x[:, 0] / r, x[:, 1] / r, 0 * r], 1)
        dur = (1 + nu) / E * k * ((1 - 2 * nu) - c * c / r**2)
        ee = e[:, :, None] * e[:, None, :]
        return dur[:, None, None] * ee + (ur(r) / r)[:, None, None] * (np.diag([1.0, 1.0, 0.0]) - ee)

    errs = []
    for refine in (2, 3, 4):
        s = (ElasticityProblem(shell, youngs=E, poisson=nu, degree_elevation=1, refine=refine)
             .dirichlet("umin", 0.0, components="y").dirichlet("umax", 0.0, components="x")
             .dirichlet("wmin", 0.0, components="z").dirichlet("wmax", 0.0, components="z")
             .pressure("vmin", p).solve())
        errs.append((s.l2_error(exact), s.h1_error(grad)))
    # one unconstrained patch with a Dirichlet side per component: auto takes the block fast diagonalization
    assert s.info["solver"]["method"] == "fd-cg"
    rates = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all(rates[-1] > [3.7, 2.7]), rates  # p + 1 = 4 and p = 3 (measured 4.09 and 2.99)
    rng = np.random.default_rng(1)
    r, t = rng.uniform(a, c, 50), rng.uniform(0, np.pi / 2, 50)
    x = np.stack([r * np.cos(t), r * np.sin(t), rng.uniform(0, 0.2, 50)], 1)
    hoop = k * (1 + c * c / r**2)
    u = s.displacement(x)
    er = np.stack([np.cos(t), np.sin(t), 0 * t], 1)
    et = np.stack([-np.sin(t), np.cos(t), 0 * t], 1)
    S = s.stress(x)
    assert np.abs(np.sum(u * er, 1) - ur(r)).max() < 1e-5 * ur(r).max()  # measured 5.4e-7
    assert np.abs(np.einsum("ni,nij,nj->n", et, S, et) - hoop).max() < 1e-4 * hoop.max()  # measured 2.8e-5
    # the pressure's resultant on the quarter's inner face: p a h along (1, 1)
    assert np.allclose(s.info["applied_N"]["vmin"], [p * a * 0.2, p * a * 0.2, 0.0], rtol=1e-9)


def test_free_thermal_expansion_of_a_homogeneous_body_is_stress_free():
    body = pr.box((1.0, 2.0, 1.0), degrees=(2, 2, 2), elements=(2, 2, 2))  # plane faces: rollers on three of them
    heat = HeatProblem(body, conductivity=3.0).dirichlet("wmin", 80.0).dirichlet("wmax", 20.0).solve()
    # a uniform temperature rise: free expansion, held only against rigid motion (rollers on three faces)
    s = (ElasticityProblem(body, youngs=69e9, poisson=0.33).thermal(70.0, 23e-6, reference=20.0)
         .dirichlet("umin", 0.0, components="x").dirichlet("vmin", 0.0, components="y")
         .dirichlet("wmin", 0.0, components="z").solve())
    x = _inside_points(s)
    assert np.abs(s.stress(x)).max() < 1e-9 * 69e9 * 23e-6 * 50
    assert s.info["work"]["thermal"]
    # held against rigid motion only (3-2-1 at three patch corners): a curved body expands stress free too
    twisted = pr.twisted(body, 0.3, axis_point=(0.5, 1.0))
    r = ElasticityProblem(twisted, youngs=69e9, poisson=0.33).thermal(70.0, 23e-6, reference=20.0).hold_rigid().solve()
    xt = _inside_points(r)
    assert np.abs(r.stress(xt)).max() < 1e-9 * 69e9 * 23e-6 * 50
    assert np.abs(r.displacement(xt)).max() > 1e-3  # it did expand (2 m x 23e-6 x 50 K = 2.3 mm)
    # a temperature field from the heat solution: a graded body stresses, and the stress tensor is symmetric
    g = (ElasticityProblem(body, youngs=69e9, poisson=0.33).thermal(heat, 23e-6, reference=20.0)
         .dirichlet("wmin", 0.0).solve())
    S = g.stress(x)
    assert np.abs(S - np.transpose(S, (0, 2, 1))).max() < 1e-9 * np.abs(S).max() and np.abs(S).max() > 1e6
    assert g.info["work"]["relative_error"] < 1e-9


@pytest.mark.parametrize("build, match", [
    (lambda m: ElasticityProblem(m, youngs=1.0, poisson=0.5), r"Poisson's ratio must lie in \(-1, 0.5\)"),
    (lambda m: ElasticityProblem(m, youngs=-1.0, poisson=0.3), r"Young's modulus must be a finite positive number"),
    (lambda m: ElasticityProblem(m, youngs=float("nan"), poisson=0.3), r"Young's modulus must be a finite positive"),
    (lambda m: ElasticityProblem(m, youngs=1.0, poisson=0.3).dirichlet("umin", 0.0, components="xw"),
     r"components must be a string of distinct letters from 'xyz'"),
    (lambda m: ElasticityProblem(m, youngs=1.0, poisson=0.3).traction("nowhere", [1, 0, 0]),
     r"unknown boundary tag 'nowhere'"),
    (lambda m: ElasticityProblem(m, youngs=1.0, poisson=0.3).traction("umax", [1, 0]),
     r"traction on 'umax' must be three finite numbers"),
    (lambda m: ElasticityProblem(m, youngs=lambda x: 1.0 - 2 * x[:, 0], poisson=0.3).dirichlet("umin").solve(),
     r"Young's modulus must be positive, but is -0.77"),
    (lambda m: ElasticityProblem(m, youngs=1.0, poisson=0.3).dirichlet("umin").solve().l2_error(lambda x: x[:, 0]),
     r"exact must return shape \(\d+, 3\) for x of shape \(\d+, 3\), got \(\d+,\)"),
    (lambda m: ElasticityProblem(m, youngs=1.0, poisson=0.3).dirichlet("umin").solve().h1_error(lambda x: x),
     r"exact_grad must return shape \(\d+, 3, 3\) for x of shape \(\d+, 3\), got \(\d+, 3\)"),
    (lambda m: ElasticityProblem(m, youngs=1.0, poisson=0.3).dirichlet("umin", 0.0, components="z").hold_rigid()
     .traction("umax", [0, 0, 1]).solve(), r"hold_rigid pins three corners .* conditions on 'umin' already hold"),
    (lambda m: ElasticityProblem(m, youngs=1.0, poisson=0.3).dirichlet("umin").traction("umin", [1, 0, 0]).solve(),
     r"the traction on 'umin' has an x component on patch 0 face umin, where the displacement condition on the faces "
     r"tagged 'umin' prescribes x"),
    (lambda m: ElasticityProblem(m, youngs=1.0, poisson=0.3).dirichlet("umin").dirichlet("umax", 0.0, components="z")
     .traction("umax", [0, 0, 1]).solve(), r"the traction on 'umax' has a z component"),
    (lambda m: ElasticityProblem(m, youngs=1.0, poisson=0.3).dirichlet("umin", 0.0, components="x")
     .dirichlet("vmin").pressure("umin", 1.0).solve(), r"the pressure on 'umin' has an x component"),
    (lambda m: ElasticityProblem(m, youngs=1.0, poisson=0.3).dirichlet("boundary").traction("rest", [0, 0, 1]).solve(),
     r"tag 'rest' names no face here \(the other conditions cover them all\)"),
])
def test_bad_elastic_input_is_refused_naming_it(build, match):
    with pytest.raises(ProblemError, match=match):
        build(pr.box(degrees=(2, 2, 2)))


def test_loads_on_free_components_of_a_held_face_are_applied():
    # held vertically on umax (rollers), pulled along x there and pressed on vmax, whose normal is y: the loads
    # act where nothing is prescribed (a pressure's round-off normal components along x or z are not loads)
    m = pr.twisted(pr.box(degrees=(2, 2, 2), elements=(2, 2, 2)), 0.2, axis_point=(0.5, 0.5))
    s = (ElasticityProblem(m, youngs=1.0, poisson=0.3).dirichlet("umin").dirichlet("umax", 0.0, components="z")
         .traction("umax", [1e-3, 0, 0]).solve())
    pulled = s.info["applied_N"]["umax"][0]  # 1e-3 times the twisted face's area
    assert s.info["work"]["relative_error"] < 1e-9 and pulled > 1e-3
    assert abs(s.reaction("umin")[0] + s.reaction("umax")[0] + pulled) < 1e-9 * pulled  # x: balanced
    c, s_ = np.cos(np.pi / 2), np.sin(np.pi / 2)  # c = 6e-17: vmax's normal is -x with round-off along y
    box = pr.box(degrees=(2, 2, 2), elements=(2, 2, 2)).affine(np.array([[c, -s_, 0], [s_, c, 0], [0, 0, 1.0]]))
    r = (ElasticityProblem(box, youngs=1.0, poisson=0.3).dirichlet("vmax", 0.0, components="yz").dirichlet("vmin")
         .pressure("vmax", 1e-3).solve())
    assert abs(r.reaction("vmin")[0] + 1e-3) < 1e-9  # the pressure pushes the body onto its support


def test_free_rigid_motions_are_refused_naming_them():
    p = ElasticityProblem(pr.box(degrees=(2, 2, 2)), youngs=1.0, poisson=0.3)
    with pytest.raises(SingularProblemError, match=r"leave 3 rigid-body motions of the model free: translation "
                                                   r"along x, translation along y, rotation about z"):
        p.dirichlet("wmin", 0.0, components="z").solve()
    with pytest.raises(SingularProblemError, match="leave 6 rigid-body motions"):
        ElasticityProblem(pr.box(), youngs=1.0, poisson=0.3).traction("umax", [1, 0, 0]).solve()


def test_vtu_of_an_elastic_solution_holds_displacement_stress_and_von_mises(tmp_path):
    import meshio
    import pyvista as pv

    from iga import write_vtu

    ms = tiling.regular(pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2)), L.cross(), (2, 1, 1))
    s = ElasticityProblem(ms, youngs=1e9, poisson=0.25).dirichlet("umin", 0.0).traction("umax", [1e5, 0, 2e4]).solve()
    path = write_vtu(tmp_path / "lattice.vtu", s, samples=2)
    grid, mesh = pv.read(path), meshio.read(path)
    for name in ("displacement", "stress", "von_mises", "youngs_modulus"):
        assert np.allclose(grid.point_data[name], mesh.point_data[name])
    pts = grid.points[::37]
    assert np.abs(grid.point_data["displacement"][::37] - s.displacement(pts)).max() < 1e-9 * np.abs(s.u).max()
    S = s.stress(pts)
    voigt = np.stack([S[:, 0, 0], S[:, 1, 1], S[:, 2, 2], S[:, 0, 1], S[:, 0, 2], S[:, 1, 2]], 1)
    inner = ~np.isin(np.arange(grid.n_points)[::37], np.flatnonzero(_welded(grid)))
    assert np.abs(grid.point_data["stress"][::37][inner] - voigt[inner]).max() < 1e-6 * np.abs(voigt).max()
    assert np.allclose(grid.point_data["von_mises"][::37][inner], s.von_mises(pts)[inner], rtol=1e-6, atol=1e-3)
    bez_path = write_vtu(tmp_path / "lattice_bezier.vtu", s, cells="bezier")
    bez = pv.read(bez_path)
    corners = np.concatenate([bez.get_cell(i).point_ids[:8] for i in range(0, bez.n_cells, 7)])
    got = bez.point_data["displacement"][corners]
    assert np.abs(got - s.displacement(bez.points[corners])).max() < 1e-9 * np.abs(s.u).max()
    from helpers import decode_appended_vtu  # the second reader of the Bezier file (meshio has none)

    raw = decode_appended_vtu(bez_path)
    assert np.array_equal(raw["displacement"].reshape(-1, 3), bez.point_data["displacement"])


def _welded(grid):
    """Points shared by cells of different patches (where written stress is the mean of both sides)."""
    patch = grid.cell_data["patch"]
    owner = np.full(grid.n_points, -1)
    shared = np.zeros(grid.n_points, bool)
    cells = grid.cells.reshape(-1, 9)[:, 1:]
    for c, p in zip(cells, patch):
        seen = owner[c]
        shared[c[(seen >= 0) & (seen != p)]] = True
        owner[c] = p
    return shared


def test_elber_fig12_ring_of_cross_tiles_moved_at_the_top_outer_ring():
    D = pr.annulus(1.0, 2.0, 1.0, angle=2 * np.pi)
    ms = tiling.regular(D, L.cross(), (3, 2, 2))  # 48 cross tiles, 336 trivariates

    def radial(pi):
        P = ms.patches[pi]
        return float((P.placement[:, :3] @ np.full(3, 0.5) + P.placement[:, 3])[1])

    ms.tags["clamped"] = [f for f in ms.tags["wmin"] if radial(f[0]) < 0.5]
    ms.tags["moved"] = [f for f in ms.tags["wmax"] if radial(f[0]) > 0.5]
    assert ms.n_tiles == 48 and len(ms.patches) == 336 and len(ms.tags["clamped"]) == len(ms.tags["moved"]) == 12
    s = ElasticityProblem(ms, youngs=1.0, poisson=0.3).dirichlet("clamped", 0.0).dirichlet("moved", [0, 0, 0.5]).solve()
    top = np.concatenate([s.problem.faces([f])[0].x for f in ms.tags["moved"]])
    assert np.abs(s.displacement(top) - [0, 0, 0.5]).max() < 1e-9
    Rc, Rm = s.reaction("clamped"), s.reaction("moved")
    assert Rm[2] > 0 and np.abs(Rc + Rm).max() < 1e-9 * Rm[2] and np.abs(Rm[:2]).max() < 1e-9 * Rm[2]
    assert s.info["work"]["relative_error"] < 1e-9


def test_a_cantilever_of_square_section_bends_as_timoshenko_beam_theory_says():
    Lb, b, E, nu, P = 10.0, 1.0, 1e3, 0.3, 1e-2
    I, G, A = b**4 / 12, E / (2 * (1 + nu)), b * b
    kappa = 10 * (1 + nu) / (12 + 11 * nu)  # Cowper's shear coefficient of a rectangle
    delta = P * Lb**3 / (3 * E * I) + P * Lb / (kappa * G * A)
    s = (ElasticityProblem(pr.box((Lb, b, b), degrees=(3, 3, 3), elements=(20, 2, 2)), youngs=E, poisson=nu)
         .dirichlet("umin", 0.0).traction("umax", [0.0, 0.0, -P / A]).solve())
    tip = -s.displacement(np.array([[Lb, 0.5, 0.5]]))[0, 2]
    assert abs(tip / delta - 1) < 0.01
    assert np.allclose(s.reaction("umin"), [0.0, 0.0, P], rtol=1e-9, atol=1e-12)  # the clamp carries the load


@pytest.mark.slow
def test_amg_with_the_rigid_modes_keeps_its_iterations_flat_under_refinement():
    # measured 14, 16, 15 (AMG, 1e-8; 44 with the constants only as near-nullspace)
    its, fd, u = [], [], []
    x = np.random.default_rng(2).uniform(0.05, 0.95, (20, 3))
    for n in (4, 8, 16):
        geo = pr.twisted(pr.box(degrees=(2, 2, 2), elements=(n, n, n)), 0.5, axis_point=(0.5, 0.5))
        for solver, out in (("amg-cg", its), ("fd-cg", fd)):
            s = (ElasticityProblem(geo, youngs=1.0, poisson=0.3).dirichlet("umin", 0.0)
                 .traction("umax", [0, 0, 1e-3]).solve(solver=solver, tol=1e-10))
            out.append(s.info["solver"]["iterations"])
            u.append(s.displacement(geo(x)))
        assert np.abs(u[-1] - u[-2]).max() < 1e-7 * np.abs(u[-1]).max()  # the two solvers agree
    assert max(its) <= 1.3 * min(its) and max(its) < 30, its
    # the block fast diagonalization (one Kronecker sum per component) is flat too: 37, 39, 40 at 1e-8
    assert max(fd) <= 1.3 * min(fd) and max(fd) < 70, fd


def test_amg_aggregates_by_node_and_stays_within_twice_heats_iterations_on_a_lattice():
    import scipy.sparse as sp

    import solvers

    twisted = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5))
    ms = tiling.regular(twisted, L.cross(), (3, 3, 3))
    h = HeatProblem(ms, degree_elevation=1).dirichlet("umin", 0.0).neumann("umax", 1.0).solve(solver="amg-cg",
                                                                                                tol=1e-8)
    e = (ElasticityProblem(ms, youngs=1.0, poisson=0.3, degree_elevation=1).dirichlet("umin", 0.0)
         .traction("umax", [0, 0, 1e-3]).solve(solver="amg-cg", tol=1e-8))
    # measured 11 and 18 (25-28 with unknown-wise aggregation, which splits a node's components); the thin
    # arms bend, which the rigid modes of a large aggregate do not capture
    assert e.info["solver"]["iterations"] <= 2 * h.info["solver"]["iterations"], (h.info["solver"], e.info["solver"])
    small = tiling.regular(twisted, L.cross(), (2, 1, 1))
    s = (ElasticityProblem(small, youngs=1.0, poisson=0.3, degree_elevation=1).dirichlet("umin", 0.0)
         .dirichlet("umax", 0.0, components="z").traction("umax", [1e-3, 0, 0]))  # a partly prescribed node side
    direct = s.solve(solver="direct")
    x = _inside_points(direct)
    u = [direct.displacement(x), s.solve(solver="amg-cg", tol=1e-12).displacement(x)]
    assert np.abs(u[0] - u[1]).max() < 1e-8 * np.abs(u[0]).max()
    with pytest.raises(solvers.SolverError, match="node_slots must be 6 distinct"):
        solvers.solve(sp.identity(6, format="csr"), np.ones(6), method="amg-cg", node_slots=[0, 1, 2, 3, 4, 4])


def test_thermal_stress_of_the_graded_demo_sink_balances_and_is_symmetric():
    from iga.app.pipeline import vertical_heat_sink_map
    from tiling.materials import graded_channel

    D = vertical_heat_sink_map()
    for ch, near, far in (("k", 205.0, 54.0), ("E", 69e9, 193e9), ("nu", 0.33, 0.29), ("alpha", 23e-6, 17.3e-6)):
        D = graded_channel(D, ch, near=near, far=far, face="wmin")
    sink = tiling.hierarchical(D, L.heat_sink_t2(), (2, 2), levels=2, scale=0.5)
    heat = HeatProblem(sink, conductivity="k").neumann("branch-in", 1515.8).robin("exterior", 5.0, 30.0).solve()
    s = (ElasticityProblem(sink, youngs="E", poisson="nu").thermal(heat, "alpha", reference=20.0)
         .dirichlet("branch-in", 0.0, components="z").dirichlet("umin", 0.0, components="x")
         .dirichlet("vmin", 0.0, components="y").solve())
    assert s.info["work"]["relative_error"] < 1e-9
    x = _inside_points(s)
    S = s.stress(x)
    assert np.abs(S - np.transpose(S, (0, 2, 1))).max() < 1e-9 * np.abs(S).max()
    assert np.abs(S).max() > 1e3  # graded expansion and a temperature gradient: stressed
    # no external load: the rollers carry nothing (against the internal forces, stress x the base's area)
    R = s.reaction("branch-in") + s.reaction("umin") + s.reaction("vmin")
    assert np.abs(R).max() < 1e-6 * np.abs(S).max() * 0.06 * 0.06


def _dense_elastic_stiffness(problem):
    """The stiffness of a one-patch problem by plain quadrature, independent of the assembly: SciPy's B-spline
    basis (values and derivatives) on the space's Gauss grid, physical gradients through J^-T per point, and
    K^{ab} = sum_q w |det J| (lambda d_a N_i d_b N_j + mu d_b N_i d_a N_j + mu delta_ab grad N_i . grad N_j)."""
    from scipy.interpolate import BSpline as SciBSpline

    from geometry.patches.chain import patch_geometry_grid
    from iga.elasticity.forms import lame

    space = problem.spaces[0]
    tables = []
    for d, q in zip(space.dirs, space.qaxes):
        basis = SciBSpline(d.knots, np.eye(len(d.knots) - d.degree - 1), d.degree)
        tables.append((basis(q), basis.derivative()(q)))  # (nq, n) each
    grads_hat = []
    for r in range(3):
        M = np.ones((1, 1))
        for k in range(3):
            M = np.kron(M, tables[k][int(k == r)])
        grads_hat.append(M)  # d N_i / d u_r at the grid points (C order), (nq, ndof)
    x, J, _ = patch_geometry_grid(problem.model.patches[0], space.qaxes)
    Jinv = np.linalg.inv(J)  # Jinv[q, r, a] = d u_r / d x_a
    grads = [sum(Jinv[:, r, a][:, None] * grads_hat[r] for r in range(3)) for a in range(3)]
    w = np.einsum("i,j,k->ijk", *(d.qw for d in space.dirs)).ravel() * np.abs(np.linalg.det(J))
    lam, mu = lame(problem.youngs.values(x, {}, "test"), problem.poisson.values(x, {}, "test"), "test")
    lw, mw = (lam * w)[:, None], (mu * w)[:, None]
    lap = sum(grads[c].T @ (mw * grads[c]) for c in range(3))
    return np.block([[grads[a].T @ (lw * grads[b]) + grads[b].T @ (mw * grads[a]) + (lap if a == b else 0)
                      for b in range(3)] for a in range(3)])


@pytest.mark.parametrize("compiled", [False, True])
def test_the_block_assembly_equals_plain_quadrature_with_scipy_basis_functions(compiled, monkeypatch):
    from iga.elasticity import volume as elastic_volume
    from iga.assembly import compiled as fast_assembly

    if compiled and not fast_assembly.AVAILABLE:
        pytest.skip("numba is not installed")
    monkeypatch.setattr(fast_assembly, "MIN_POINTS", 1000 if compiled else 10**12)  # which path the blocks take
    geo = pr.twisted(pr.box(degrees=(2, 2, 2), elements=(4, 4, 4)), 0.5, axis_point=(0.5, 0.5))
    p = ElasticityProblem(geo, youngs=lambda x: 1.0 + x[:, 0], poisson=lambda x: 0.2 + 0.1 * x[:, 1])
    assert fast_assembly.applies(p.spaces[0], 1, terms=elastic_volume.ELASTIC_TERMS) == compiled
    K = elastic_volume.ElasticVolume(p.disc).assemble(p.material)[0]
    ref = _dense_elastic_stiffness(p)
    assert abs(K.toarray() - ref).max() <= 1e-12 * abs(ref).max()
    assert abs(K - K.T).max() <= 1e-12 * abs(K).max()


def test_the_compiled_assembly_of_batched_patches_equals_the_numpy_one(monkeypatch):
    """Several patches per compiled batch (a lattice of cross tiles, patches sharing spaces): their rows,
    columns and the lower blocks' copies land where the NumPy path puts them, whatever each patch's offset."""
    from iga.elasticity import volume as elastic_volume
    from iga.assembly import compiled as fast_assembly

    if not fast_assembly.AVAILABLE:
        pytest.skip("numba is not installed")
    twisted = pr.twisted(pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(1.0, 0.5))
    ms = tiling.regular(twisted, L.cross(), (2, 2, 1))
    p = ElasticityProblem(ms, youngs=lambda x: 1.0 + x[:, 0], poisson=0.3, degree_elevation=1)
    vol = elastic_volume.ElasticVolume(p.disc)
    monkeypatch.setattr(fast_assembly, "MIN_POINTS", 10**12)
    ref = vol.assemble(p.material)[0]
    monkeypatch.setattr(fast_assembly, "MIN_POINTS", 1)
    groups = p.disc.volume.groups.values()
    assert any(len(g) > 1 for g in groups) and all(fast_assembly.applies(p.spaces[g[0]], len(g)) for g in groups)
    K = vol.assemble(p.material)[0]
    assert np.array_equal(K.indptr, ref.indptr) and np.array_equal(K.indices, ref.indices)
    assert abs(K - ref).max() <= 1e-12 * abs(ref).max()


def test_the_component_major_operator_is_the_block_matrix_of_its_patches():
    import scipy.sparse as sp

    from iga.assembly.tensor import CSRPattern
    from iga.errors import ProblemError
    from iga.assembly.vector_csr import VectorCSR

    rng = np.random.default_rng(3)
    # four patches, two patterns; 0, 2 and 3 written together, at uneven steps (no strided view)
    sizes = (300, 120, 300, 300)
    pats = []
    for seed, n in enumerate(sizes[:2]):
        A = sp.random(n, n, density=0.05, random_state=4 + seed, format="csr") + sp.eye(n, format="csr")
        A.sort_indices()
        pats.append(CSRPattern(A.indptr.astype(np.int64), A.indices, None, None, n))
    pats += [pats[0], pats[0]]
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    out = VectorCSR(offsets, [len(p.indices) for p in pats])
    blocks = [{(a, b): rng.standard_normal(len(p.indices)) for a in range(3) for b in range(3)} for p in pats]
    out.put([1], pats[1], {ab: v[None] for ab, v in blocks[1].items()})
    with pytest.raises(ProblemError, match=r"patches \[0, 2, 3\] were not assembled"):
        out.matrix()
    out.put([0, 2, 3], pats[0], {ab: np.stack([blocks[m][ab] for m in (0, 2, 3)]) for ab in blocks[0]})
    K = out.matrix()
    n = offsets[-1]

    def block(a, b):  # the (n, n) block-diagonal matrix of block (a, b) over the three patches
        return sp.block_diag([sp.csr_matrix((blocks[m][(a, b)], p.indices, p.indptr), shape=(p.n, p.n))
                              for m, p in enumerate(pats)], format="csr")

    ref = sp.bmat([[block(a, b) for b in range(3)] for a in range(3)]).tocsr()
    ref.sort_indices()
    assert K.shape == (3 * n, 3 * n) and K.has_sorted_indices
    assert np.array_equal(K.indptr, ref.indptr) and np.array_equal(K.indices, ref.indices)
    assert np.array_equal(K.data, ref.data)


def test_the_compiled_elastic_blocks_equal_the_numpy_ones_on_batches_of_patches(monkeypatch):
    from iga.elasticity import volume as elastic_volume
    from iga.assembly import compiled as fast_assembly

    if not fast_assembly.AVAILABLE:
        pytest.skip("numba is not installed")
    twisted = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5))
    ms = tiling.regular(twisted, L.cross(), (2, 2, 2))  # each of the tile's patches: a batch of 8 placements
    p = ElasticityProblem(ms, youngs=lambda x: 1.0 + x[:, 0], poisson=0.3, degree_elevation=1)
    p.body_force(lambda x: np.c_[x[:, 1], -x[:, 0], np.ones(len(x))]).thermal(lambda x: 1.0 + x[:, 2] ** 2, 1e-3)
    assert max(len(g) for g in p.disc.volume.groups.values()) == 8
    monkeypatch.setattr(fast_assembly, "MIN_POINTS", 10**12)
    ref, f_ref, w_ref = elastic_volume.ElasticVolume(p.disc).assemble(p.material, p.body, p.thermal_strain)
    monkeypatch.setattr(fast_assembly, "MIN_POINTS", 100)  # every batch compiled
    K, f, w = elastic_volume.ElasticVolume(p.disc).assemble(p.material, p.body, p.thermal_strain)
    assert K.nnz == ref.nnz and abs(K - ref).max() <= 1e-12 * abs(ref).max()
    # the body and thermal loads from the compiled metric fields equal the NumPy ones
    assert np.abs(f - f_ref).max() <= 1e-12 * np.abs(f_ref).max() and np.abs(f_ref).max() > 0
    assert np.allclose(w["body"], w_ref["body"], rtol=1e-12, atol=0)
