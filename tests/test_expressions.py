"""Formulas of the position as pipeline values (iga.expressions): their grammar, their values, and the
fields they prescribe reproduced exactly through `iga run`."""

import numpy as np
import pytest

from iga import ProblemError
from iga.expressions import Expression, VectorExpression
from iga.app.pipeline import run_pipeline


def test_formulas_evaluate_as_numpy_does_at_random_points():
    rng = np.random.default_rng(8)
    x = rng.uniform(-1, 2, (500, 3))
    X, Y, Z = x.T
    cases = {
        "20 + 3000 * z": 20 + 3000 * Z,
        "-x ** 2 + y % 0.3 - +z / 7": -X ** 2 + Y % 0.3 - Z / 7,
        "sin(pi * x) * exp(-y) + sqrt(abs(z)) + hypot(x, y)": np.sin(np.pi * X) * np.exp(-Y) + np.sqrt(np.abs(Z))
        + np.hypot(X, Y),
        "where(x < 0.5, 80, where(0.5 <= x <= 1.5, 60, e))": np.where(X < 0.5, 80, np.where((X >= 0.5) & (X <= 1.5), 60,
                                                                                           np.e)),
        "maximum(x, y) - minimum(y, z) + arctan2(y, x) + floor(2 * z)": np.maximum(X, Y) - np.minimum(Y, Z)
        + np.arctan2(Y, X) + np.floor(2 * Z),
        "3": np.full(len(x), 3.0),
    }
    for text, want in cases.items():
        got = Expression(text)(x)
        assert got.shape == (len(x),) and np.allclose(got, want, rtol=1e-15, atol=1e-13), text
    v = VectorExpression([0.0, Expression("x"), 2])(x)
    assert v.shape == (len(x), 3) and np.array_equal(v[:, 1], X) and np.all(v[:, 0] == 0) and np.all(v[:, 2] == 2)


@pytest.mark.parametrize("text, why", [
    ("80 + * x", "is not a formula"),
    ("80 + t", "names 't', which is neither a coordinate nor a constant"),
    ("x.__class__", "uses attribute"),
    ("__import__('os')", "uses call"),
    ("open('f')", "uses call"),
    ("x[0]", "uses subscript"),
    ("(lambda: 1)()", "uses call"),
    ("sin(x=1)", "passes keywords to sin"),
    ("x < 1", "compares outside where"),
    ("where(x == 1, 1, 2)", "other than <, <=, >, >="),
    ("'a' + x", "holds 'a', which is not a number"),
    ("True", "holds True"),
    ("[x, y]", "uses list"),
])
def test_anything_but_a_formula_is_refused_naming_the_key(text, why):
    pattern = "config key bc\\[0\\].value: .*" + why.replace("(", "\\(").replace(")", "\\)")
    with pytest.raises(ProblemError, match=pattern):
        Expression(text, "config key bc[0].value")


def test_formulas_too_long_or_too_deep_are_refused_not_crashed():
    with pytest.raises(ProblemError, match="a formula of 3000 characters is longer than 2000"):
        Expression("x" * 3000)
    with pytest.raises(ProblemError, match=r"nested too deeply|is not a formula") as info:
        Expression("(" * 300 + "x" + ")" * 300)(np.ones((2, 3)))  # too deep for Python's own parser
    assert len(str(info.value)) < 400  # the text is cut in the message
    # long formulas are compiled and evaluated without recursion: 1,500 signs, a sum of 999 terms
    assert Expression("-" * 1500 + "x")(np.full((2, 3), 2.0))[0] == 2.0
    assert Expression("+".join(["x"] * 999))(np.ones((2, 3)))[0] == 999


def test_a_formula_that_is_not_finite_somewhere_names_the_point():
    f = Expression("log(x)", "config key bc[1].value")
    with pytest.raises(ProblemError, match=r"config key bc\[1\].value: 'log\(x\)' is not finite at "
                                           r"x = \[-1.0, 0.0, 0.0\]"):
        f(np.array([[1.0, 0, 0], [-1.0, 0, 0]]))
    with pytest.raises(ProblemError, match="is not finite"):
        Expression("10 ** 10 ** 10")(np.zeros((2, 3)))  # an overflow is inf, refused, not an OverflowError
    with pytest.raises(ProblemError, match="calls where with 1 argument; where takes 3 arguments"):
        Expression("where(x)")  # refused when read, not when evaluated


def _lattice(tmp_path, extra: str) -> dict:
    import tomllib

    text = f"""
[map]
primitive = "box"
args = {{size = [0.03, 0.03, 0.03]}}
[tile]
library = "cross"
[paving]
scheme = "regular"
counts = [2, 2, 2]
[output]
dir = "{tmp_path / 'out'}"
png = false
vtu = false
{extra}
"""
    return tomllib.loads(text)


def test_a_linear_temperature_written_as_a_formula_is_reproduced_through_a_pipeline(tmp_path):
    centres = np.array([[a, b, c] for a in (0.0075, 0.0225) for b in (0.0075, 0.0225) for c in (0.0075, 0.0225)])
    cfg = _lattice(tmp_path, f"""probes = {centres.tolist()}
[material]
conductivity = 16.0
[[bc]]
kind = "dirichlet"
tag = "boundary"
value = "20 + 1000 * x - 500 * y + 200 * z"
""")
    s = run_pipeline(cfg, progress=False)
    T = np.array(s["probes"]["temperature_C"])
    want = 20 + 1000 * centres[:, 0] - 500 * centres[:, 1] + 200 * centres[:, 2]
    assert np.abs(T - want).max() < 1e-9 * np.abs(want).max()
    # a quadratic T = 20 + 1000 x^2 takes the source -k lap T = -32000 (W/m^3): exact once the trilinear tiles'
    # spaces are raised to degree 2
    cfg["material"]["source"], cfg["bc"][0]["value"] = "-32000 + 0 * x", "20 + 1000 * x ** 2"
    cfg["output"]["dir"], cfg["solver"] = str(tmp_path / "quadratic"), {"degree_elevation": 1}
    T = np.array(run_pipeline(cfg, progress=False)["probes"]["temperature_C"])
    assert np.abs(T - (20 + 1000 * centres[:, 0] ** 2)).max() < 1e-9 * 20


def test_an_affine_displacement_written_as_formulas_is_reproduced_through_a_pipeline(tmp_path):
    E, nu, a = 1e9, 0.3, 1e-4
    cfg = _lattice(tmp_path, f"""
[physics]
kind = "elasticity"
youngs = {E}
poisson = {nu}
[[support]]
tag = "boundary"
value = [0.0, 0.0, "{a} * x"]
""")
    s = run_pipeline(cfg, progress=False)["elasticity"]
    # u = (0, 0, a x): a uniform shear strain eps_xz = a / 2, stress sigma_xz = mu a, von Mises sqrt(3) mu a
    mu = E / (2 * (1 + nu))
    assert s["max_displacement_m"] == pytest.approx(a * 0.03, rel=1e-9)
    assert s["max_von_mises_Pa"] == pytest.approx(np.sqrt(3) * mu * a, rel=1e-9)
    assert np.abs(s["reactions_N"]["boundary"]).max() < 1e-9 * mu * a * 0.03 ** 2  # a self-balanced field


FORMULAS = ["20 + 3000 * z", "-x ** 2 + y % 0.3 - +z / 7", "sin(pi * x) * exp(-y) + sqrt(abs(z)) + hypot(x, y)",
            "where(x < 0.5, 80, where(0.5 <= x <= 1.5, 60, e))", "2 ** -x ** 2", "(-x) % 0.7 - x % -0.3",
            "maximum(x, y) - minimum(y, z) + arctan2(y, x) + floor(2 * z) + ceil(x) + log10(z) + log(z)",
            "where(x > 0 and y < 0 or z > 1, arcsin(x / 3), arccos(y / 3) + arctan(z))",
            "sinh(x) + cosh(y) + tanh(z) + cos(x) + tan(y / 3)"]


def test_formulas_leave_in_gismo_syntax_that_gismo_evaluates_alike_and_come_back():
    gs = pytest.importorskip("pygismo")
    rng = np.random.default_rng(1)
    x = rng.uniform(-2, 2, (300, 3))
    x[:, 2] = np.abs(x[:, 2]) + 0.1  # inside the logarithms' domain
    for text in FORMULAS:
        f = Expression(text)
        ours, written = f(x), f.exprtk()
        theirs = gs.core.gsFunctionExpr(written, 3).eval(np.ascontiguousarray(x.T))[0]  # G+Smo's own parser
        assert np.abs(theirs - ours).max() <= 1e-14 * np.abs(ours).max(), (text, written)
        back = Expression.from_exprtk(written)(x)
        assert np.abs(back - ours).max() <= 1e-14 * np.abs(ours).max(), (text, written)
    # a hand-written G+Smo formula of the same functions reads too
    hand = Expression.from_exprtk("if(x < 1, asin(x/3)^2, max(y, z)) + atan2(y, x)")
    X, Y, Z = x.T
    assert np.allclose(hand(x), np.where(X < 1, np.arcsin(X / 3) ** 2, np.maximum(Y, Z)) + np.arctan2(Y, X),
                       rtol=1e-15, atol=1e-15)
    nested = "x"
    for _ in range(60):  # each % is written a - b floor(a / b): its operands twice
        nested = f"({nested} % 1.5)"
    with pytest.raises(ProblemError, match="more than 100000 characters in G\\+Smo's syntax"):
        Expression(nested).exprtk()
    with pytest.raises(ProblemError, match="sample.xml: the value.*is not a formula"):
        Expression.from_exprtk("x < 1 ? 2 : 3", "sample.xml: the value")  # exprtk's ternary: not this grammar


def test_a_heat_problem_with_formula_conditions_goes_to_gismo_and_back(tmp_path):
    import re

    from geometry import primitives as pr
    from iga import HeatProblem
    from iga.io.gismo import export_gismo, problem_from_gismo

    box = pr.twisted(pr.box(degrees=(2, 2, 2), elements=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5))
    p = (HeatProblem(box, conductivity=Expression("1 + x ** 2"), source=Expression("10 * sin(pi * x) * y"))
         .dirichlet("umin", Expression("20 + 30 * z ** 2"))
         .neumann("umax", Expression("where(y < 0.5, 5, -3)"))
         .robin("vmax", Expression("2 + x"), Expression("15 % 4 + y")))
    path = export_gismo(p, tmp_path / "box.xml")
    q = problem_from_gismo(path)
    s1, s2 = p.solve(tol=1e-12), q.solve(tol=1e-12)
    x = box.evaluate(np.random.default_rng(3).random((50, 3)))[:, :3]
    assert np.abs(s1.probe(x) - s2.probe(x)).max() < 1e-10 * np.abs(s1.probe(x)).max()
    gs = pytest.importorskip("pygismo")
    fd = gs.io.gsFileData(str(path))
    bc = gs.pde.gsBoundaryConditions()
    fd.getId(int(re.search(r'<boundaryConditions multipatch="\d+" id="(\d+)"', path.read_text()).group(1)), bc)
    assert bc.size() == 3
    with pytest.raises(ProblemError, match="not Python functions: give it as Expression"):
        export_gismo(HeatProblem(box).dirichlet("umin", lambda y: y[:, 0]), tmp_path / "lambda.xml")


def test_scripts_give_vector_values_as_lists_of_numbers_and_formulas():
    from geometry import primitives as pr
    from iga import ElasticityProblem

    box = pr.box(degrees=(2, 2, 2), elements=(2, 2, 2))
    x = np.random.default_rng(4).uniform(0.1, 0.9, (20, 3))
    s = ElasticityProblem(box, 1.0, 0.3).dirichlet("boundary", [0, 0, Expression("1e-3 * x")]).solve()
    assert np.abs(s.displacement(x) - np.c_[0 * x[:, :2], 1e-3 * x[:, 0]]).max() < 1e-15  # affine: exact
    t = ElasticityProblem(box, 1.0, 0.3).dirichlet("boundary", Expression("1e-3 * y")).solve()  # all three
    assert np.abs(t.displacement(x) - 1e-3 * x[:, [1, 1, 1]]).max() < 1e-15
    with pytest.raises(ProblemError, match=r"traction on 'umax' callable must return shape \(\d+, 3\)"):
        ElasticityProblem(box, 1.0, 0.3).dirichlet("umin").traction("umax", Expression("x")).solve()


def test_materials_take_formulas_as_tables_where_a_string_is_a_channel(tmp_path):
    from iga.app.config import validate

    # k = 1 + 100 x and T = ln(1 + 100 x) / ln 4: k dT/dx is constant, so div(k grad T) = 0 in any geometry;
    # T on every free face of the lattice (a formula too) makes it the solution, up to discretisation error
    centres = np.array([[a, b, c] for a in (0.0075, 0.0225) for b in (0.0075, 0.0225) for c in (0.0075, 0.0225)])
    want = np.log(1 + 100 * centres[:, 0]) / np.log(4)
    errors = []
    for refine in (0, 1):
        cfg = _lattice(tmp_path / str(refine), f"""probes = {centres.tolist()}
[material]
conductivity = {{formula = "1 + 100 * x"}}
[[bc]]
kind = "dirichlet"
tag = "boundary"
value = "log(1 + 100 * x) / log(4)"
[solver]
degree_elevation = 1
refine = {refine}
""")
        errors.append(np.abs(np.array(run_pipeline(cfg, progress=False)["probes"]["temperature_C"]) - want).max())
    assert errors[1] < 1e-5 and errors[1] < errors[0] / 8  # to ln(1 + 100 x) / ln 4 at degree 2: 9.7e-5, 5.6e-6
    bad = _lattice(tmp_path, '[material]\nconductivity = {formula = 16}\n[[bc]]\nkind = "dirichlet"\ntag = "umin"\n')
    with pytest.raises(ProblemError, match=r"material\.conductivity\.formula: must be a formula of x, y, z"):
        validate(bad)
    bad["material"]["conductivity"] = {"formula": "16", "unit": "W/mK"}
    with pytest.raises(ProblemError, match=r"unknown config key material\.conductivity\.'unit'"):
        validate(bad)
    elastic = _lattice(tmp_path, """
[physics]
kind = "elasticity"
youngs = {formula = "1e9 * (1 + 10 * x)"}
poisson = {formula = "0.3 - x"}
[[support]]
tag = "boundary"
value = [0.0, 0.0, "1e-4 * x"]
""")
    s = run_pipeline(elastic, progress=False)["elasticity"]
    assert s["max_von_mises_Pa"] > 0 and s["work"]["relative_error"] < 1e-9
