"""Graded macro models: effective tensors tabulated over a tile family's parameter, as conductivity fields.

A lattice graded along a parameter p (the arm width of :func:`tiling.library.cross`, varying across the part)
is, far from its boundaries, a continuum whose conductivity at x is the effective tensor K_eff(p(x)) of the
tile with the local p (first-order homogenisation; :mod:`iga.homogenisation.cells`).  :func:`effective_table` solves the
cell problems on a grid of parameter values and interpolates every tensor component by a cubic spline in p
(:class:`scipy.interpolate.CubicSpline`, not-a-knot); :func:`macro_map` writes the interpolated tensor into
six conductivity channels of the deformation map, from the map's own channel of p, for one
:class:`iga.HeatProblem` on the map alone: a macro model, at a fraction of the unknowns of the full lattice.

The tensor is the cell's, in the tile's frame: exact where the map takes every cell to a scaled rigid motion of
the unit cube and the tensor is isotropic (the cubic cross tile, K_eff = k_eff I); where cells are stretched,
the conductivity along the stretch keeps its cell value to first order (its conducting path scales with the
cell), which the comparison with the full lattice measures (``tests/test_macro.py``,
``benchmarks/homogenization.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from geometry import BSpline
from geometry.errors import ToolkitError, show
from geometry.numbers import TINY, is_integer
from geometry.resources import check_memory
from tiling.materials import interpolate_channel

from iga.heat.coefficients import TENSOR_PAIRS
from iga.errors import ProblemError
from iga.elasticity.material import CubicMaterial
from iga.homogenisation.cells import effective_conductivity, effective_stiffness

__all__ = ["EffectiveTable", "effective_table", "macro_map", "StiffnessTable", "stiffness_table", "cubic_constants"]


@dataclass
class EffectiveTable:
    """Effective conductivity tensors ``tensors`` (n, 3, 3) (units of the conductivity) at the family's parameter
    values ``values`` (n,), increasing; ``name`` labels the family in messages."""

    values: np.ndarray
    tensors: np.ndarray
    name: str = "tile family"

    def __post_init__(self):
        from scipy.interpolate import CubicSpline

        comps = np.stack([self.tensors[:, r, s] for r, s in TENSOR_PAIRS], axis=1)  # (n, 6)
        self._spline = CubicSpline(self.values, comps, axis=0, bc_type="not-a-knot" if len(self.values) > 3
                                   else "natural")

    def components(self, p) -> np.ndarray:
        """The interpolated tensor components (N, 6) in the order (xx, yy, zz, xy, xz, yz) at parameters p (N,);
        a parameter outside the table is refused (no extrapolation)."""
        return self._spline(_within(self.values, p, f"the table of {self.name}",
                                   "tabulate the range the model uses (effective_table(family, values))"))

    def tensor(self, p) -> np.ndarray:
        """The interpolated tensors (N, 3, 3) at parameters p (N,)."""
        c = self.components(p)
        out = np.empty((len(c), 3, 3))
        for j, (r, s) in enumerate(TENSOR_PAIRS):
            out[:, r, s] = out[:, s, r] = c[:, j]
        return out


def effective_table(family, values, conductivity=1.0, degree_elevation: int = 1, refine: int = 0,
                    name: str | None = None) -> EffectiveTable:
    """:func:`iga.effective_conductivity` of ``family(p)`` (a tile) at every p of ``values`` (>= 2 increasing
    numbers), as an :class:`EffectiveTable`; ``conductivity``, ``degree_elevation``, ``refine`` as there."""
    v = _increasing(values, "effective_table")
    if not callable(family):
        raise ProblemError(f"effective_table: family must be a callable p -> tile (e.g. tiling.library.cross), got "
                           f"{show(family)}")
    tensors = np.stack([effective_conductivity(_member(family, float(p)), conductivity, degree_elevation, refine)
                        for p in v])
    return EffectiveTable(v, tensors, name or getattr(family, "__name__", "tile family"))


#: relative departure from cubic symmetry above which stiffness_table refuses a family (its tensor is not C11,
#: C12, C44 about x, y, z: another symmetry, which a CubicMaterial would misrepresent)
CUBIC_MARGIN = 1e-6


@dataclass
class StiffnessTable:
    """The effective stiffness of a tile family of cubic symmetry (a cross lattice) at the family's parameter
    values ``values`` (n,), increasing: ``constants`` (n, 3) = (C11, C12, C44) in Pa and the solid volume
    ``fractions`` (n,); ``cubic_error`` the largest relative departure of the tensors from cubic symmetry; ``name``
    labels the family.  Between the values, every constant and the fraction are cubic splines in p
    (:class:`scipy.interpolate.CubicSpline`, not-a-knot), with their exact derivatives: the constants of a
    :class:`iga.CubicMaterial` of a channel (:meth:`material`), a graded lattice's macro model."""

    values: np.ndarray
    constants: np.ndarray
    fractions: np.ndarray
    cubic_error: float = 0.0
    name: str = "tile family"

    def __post_init__(self):
        from scipy.interpolate import CubicSpline

        bc = "not-a-knot" if len(self.values) > 3 else "natural"
        self._spline = CubicSpline(self.values, np.column_stack([self.constants, self.fractions]), axis=0, bc_type=bc)
        self._slope = self._spline.derivative()

    def _at(self, spline, p) -> np.ndarray:
        return spline(_within(self.values, p, f"the stiffness table of {self.name}", "tabulate the range the model "
                             "uses (stiffness_table(family, values, ...)) or bound the design within it"))

    def constants_at(self, p) -> np.ndarray:
        """(C11, C12, C44) (N, 3) in Pa at parameters p (N,); outside the table refused (no extrapolation)."""
        return self._at(self._spline, p)[:, :3]

    def slopes(self, p) -> np.ndarray:
        """d(C11, C12, C44)/dp (N, 3) in Pa per unit of p."""
        return self._at(self._slope, p)[:, :3]

    def fraction(self, p) -> np.ndarray:
        """The solid volume fraction (N,) of the family's member at p."""
        return self._at(self._spline, p)[:, 3]

    def fraction_slope(self, p) -> np.ndarray:
        """d fraction / dp (N,)."""
        return self._at(self._slope, p)[:, 3]

    def material(self, channel: str) -> CubicMaterial:
        """The :class:`iga.CubicMaterial` whose constants are this table at the map's channel ``channel``:
        ``ElasticityProblem(D, material=table.material("t"))`` is the lattice's macro model on D."""
        return CubicMaterial(self, channel)


def stiffness_table(family, values, youngs, poisson, degree_elevation: int = 1, refine: int = 0,
                    name: str | None = None) -> StiffnessTable:
    """:func:`iga.effective_stiffness` of ``family(p)`` (a tile of cubic symmetry, e.g.
    :func:`tiling.library.cross`) made of an isotropic material (``youngs`` in Pa, ``poisson``) at every p of
    ``values`` (>= 2 increasing numbers), reduced to its cubic constants (C11 the mean of the three normal
    stiffnesses, C12 of the three couplings, C44 of the three shear ones) as a :class:`StiffnessTable`; a family
    whose tensors depart from cubic symmetry by more than :data:`CUBIC_MARGIN` (relative) is refused."""
    v = _increasing(values, "stiffness_table")
    if not callable(family):
        raise ProblemError(f"stiffness_table: family must be a callable p -> tile (e.g. tiling.library.cross), got "
                           f"{show(family)}")
    fams = [effective_stiffness(_member(family, float(p), "stiffness_table"), youngs, poisson, degree_elevation,
                                refine, diagnostics=True) for p in v]
    constants, errors = cubic_constants(np.stack([f.tensor for f in fams]))
    error = float(errors.max())
    label = name or getattr(family, "__name__", "tile family")
    if error > CUBIC_MARGIN:
        raise ProblemError(f"stiffness_table: the effective stiffness of {label} departs from cubic symmetry by "
                           f"{error:.3g} (relative); a CubicMaterial needs a family symmetric about the cell's axes "
                           "(e.g. tiling.library.cross)")
    return StiffnessTable(v, constants, np.array([f.volume_fraction for f in fams]), error, label)


def cubic_constants(C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The nearest cubic constants (N, 3) = (C11, C12, C44) of Voigt stiffness tensors C (N, 6, 6) (engineering
    shears; the means of the three normal, coupling and shear entries) and each tensor's relative departure from
    that cubic tensor (N,) (largest entry of the difference / largest entry of C)."""
    C = np.asarray(C, float).reshape(-1, 6, 6)
    n, c, g = np.arange(3), np.array([[0, 1], [0, 2], [1, 2]]), np.arange(3, 6)
    constants = np.column_stack([C[:, n, n].mean(1), C[:, c[:, 0], c[:, 1]].mean(1), C[:, g, g].mean(1)])
    cubic = np.zeros_like(C)
    cubic[:, n, n] = constants[:, :1]
    cubic[:, c[:, 0], c[:, 1]] = cubic[:, c[:, 1], c[:, 0]] = constants[:, 1:2]
    cubic[:, g, g] = constants[:, 2:]
    return constants, np.abs(C - cubic).max((1, 2)) / np.maximum(np.abs(C).max((1, 2)), TINY)


def _within(values: np.ndarray, p, what: str, fix: str) -> np.ndarray:
    """Parameters p (N,) inside the tabulated ``values`` (increasing), clipped onto them (a margin of 1e-12
    relative to their ends takes the round-off of a design's values); one outside is refused naming ``what`` and
    the ``fix`` (no extrapolation)."""
    p = np.asarray(p, float).reshape(-1)
    lo, hi = float(values[0]), float(values[-1])
    bad = ~((p >= lo - 1e-12 * max(1.0, abs(lo))) & (p <= hi + 1e-12 * max(1.0, abs(hi))))
    if bad.any():
        raise ProblemError(f"parameter {p[bad][0]:g} lies outside {what} ([{lo:g}, {hi:g}]); {fix}")
    return np.clip(p, lo, hi)


def _increasing(values, what: str) -> np.ndarray:
    v = np.asarray(values, float).reshape(-1) if np.ndim(values) else np.array([])
    if len(v) < 2 or not np.all(np.isfinite(v)) or np.any(np.diff(v) <= 0):
        raise ProblemError(f"{what} needs at least two increasing finite parameter values, got {show(values)}")
    return v


def _member(family, p: float, what: str = "effective_table"):
    """``family(p)``, a user's callable: what it raises is reported as the project's error naming it and p."""
    try:
        return family(p)
    except ToolkitError:
        raise
    except Exception as exc:  # the user's code: any exception, reported with its own words
        raise ProblemError(f"{what}: the family {show(getattr(family, '__name__', family))} failed at "
                           f"p = {p:g}: {type(exc).__name__}: {exc}") from None


#: knot spans per direction at most for macro_map (the six channels on the refined map: 8 GiB at 500^3)
_MAX_SPANS = 500


def macro_map(D: BSpline, table: EffectiveTable, parameter: str, spans: int = 8, prefix: str = "K"):
    """The map D with six conductivity channels ``K_xx`` .. ``K_yz`` (:data:`iga.heat.coefficients.TENSOR_PAIRS`
    order) from the table at D's channel ``parameter``; returns (map, the six channel names) for
    ``HeatProblem(map, conductivity=names)``.

    D is first refined (knot insertion, exact) to at least ``spans`` knot spans per direction, so that its
    spline space can carry the interpolated tensor (a quasi-interpolant at the Greville points).
    """
    if not isinstance(D, BSpline) or D.dim != 3:
        raise ProblemError(f"macro_map needs a trivariate geometry.BSpline map, got {show(D)}")
    if not isinstance(table, EffectiveTable):
        raise ProblemError(f"macro_map needs an EffectiveTable (iga.effective_table(family, values)) as its table, "
                           f"got {show(table)}")
    if not (is_integer(spans) and 1 <= spans <= _MAX_SPANS):
        raise ProblemError(f"macro_map: spans must be an integer in [1, {_MAX_SPANS}] (knot spans per direction of "
                           f"the refined map), got {show(spans)}")
    need = float(np.prod([max(spans, len(D.breakpoints(k)) - 1) + D.degrees[k] for k in range(3)]))
    check_memory(need * 8 * (D.control_points.shape[-1] + 6) * 4, f"the macro map at {spans} spans per direction",
                 ProblemError, "lower spans")
    if not isinstance(parameter, str) or parameter not in D.channels:
        raise ProblemError(f"macro_map: {show(parameter)} is not a channel of the map (its channels: "
                           f"{list(D.channels)}); grade the parameter onto it (tiling.materials.graded_channel)")
    for k in range(3):
        b = D.breakpoints(k)
        n = len(b) - 1
        if n < spans:
            per = int(np.ceil(spans / n))
            t = np.linspace(0.0, 1.0, per + 1)[1:-1]
            new = (b[:-1, None] + np.diff(b)[:, None] * t[None]).ravel()
            D = D.insert_knots(k, new)[0] if len(new) else D
    idx = 3 + list(D.channels).index(parameter)
    names = tuple(f"{prefix}_{'xyz'[r]}{'xyz'[s]}" for r, s in TENSOR_PAIRS)
    base, out = D, D
    for j, ch in enumerate(names):  # (every channel on the same Greville grid of the refined map)
        out = interpolate_channel(out, ch, lambda x, j=j: table.components(base.evaluate(x)[:, idx])[:, j])
    return out, names
