"""Formulas of the position as pipeline values (iga.expressions): their grammar, their values, and the
fields they prescribe reproduced exactly through `iga run`."""

import numpy as np
import pytest

from iga import ProblemError
from iga.expressions import Expression, VectorExpression
from iga.pipeline import run_pipeline


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
    with pytest.raises(ProblemError, match="config key bc\\[0\\].value: .*" + why.replace("(", "\\(").replace(")", "\\)")):
        Expression(text, "config key bc[0].value")


def test_formulas_too_long_or_too_deep_are_refused_not_crashed():
    with pytest.raises(ProblemError, match="a formula of 3000 characters is longer than 2000"):
        Expression("x" * 3000)
    for text in ("-" * 1500 + "x", "+".join(["x"] * 999), "(" * 300 + "x" + ")" * 300):  # RecursionErrors in ast
        with pytest.raises(ProblemError, match=r"nested too deeply|is not a formula") as info:
            Expression(text)(np.ones((2, 3)))
        assert len(str(info.value)) < 400  # the text is cut in the message
    assert Expression("+".join(["x"] * 500))(np.ones((2, 3)))[0] == 500


def test_a_formula_that_is_not_finite_somewhere_names_the_point():
    f = Expression("log(x)", "config key bc[1].value")
    with pytest.raises(ProblemError, match=r"config key bc\[1\].value: 'log\(x\)' is not finite at x = \[-1.0, 0.0, 0.0\]"):
        f(np.array([[1.0, 0, 0], [-1.0, 0, 0]]))
    with pytest.raises(ProblemError, match="is not finite"):
        Expression("10 ** 10 ** 10")(np.zeros((2, 3)))  # an overflow is inf, refused, not an OverflowError
    with pytest.raises(ProblemError, match="cannot be evaluated"):
        Expression("where(x)")(np.zeros((2, 3)))


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
