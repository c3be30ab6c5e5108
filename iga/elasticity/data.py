"""Vector-valued data of the elastic problem (displacements, tractions, body forces) and the Dirichlet data of
its three components, projected one component at a time by the scalar machinery (:mod:`iga.discretisation.dirichlet`)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from geometry.errors import show

from iga.heat.coefficients import is_number, user_values
from iga.discretisation.dirichlet import DirichletData, project_dirichlet
from iga.errors import ProblemError
from iga.expressions import Expression, VectorExpression

__all__ = ["VectorField", "component_field", "merge_dirichlet", "pin_dofs"]


class VectorField:
    """Three numbers or a callable ``v(x (N, 3)) -> (N, 3)``; with ``broadcast`` one number (or one
    :class:`iga.Expression`) serves all three; three numbers or Expressions make a callable component by component."""

    def __init__(self, spec, what: str, broadcast: bool = False):
        self.what = what
        if broadcast and (is_number(spec) or isinstance(spec, Expression)):
            spec = [spec] * 3
        if isinstance(spec, (list, tuple)) and len(spec) == 3 and any(isinstance(c, Expression) for c in spec) \
                and all(isinstance(c, Expression) or is_number(c) for c in spec):
            spec = VectorExpression(spec)
        if callable(spec):
            self.spec, self.kind = spec, "callable"
            return
        try:
            v = np.asarray(spec, float)
        except (TypeError, ValueError):
            v = None
        if v is None or v.shape != (3,) or not np.all(np.isfinite(v)) or isinstance(spec, (str, bytes)):
            one = "a number, " if broadcast else ""
            raise ProblemError(f"{what} must be {one}three finite numbers or a callable of x (N, 3) returning (N, 3), "
                               f"got {show(spec)}")
        self.spec, self.kind = v, "vector"

    def values(self, x: np.ndarray, where: str) -> np.ndarray:
        """Values (N, 3) at physical points x (N, 3)."""
        n = len(x)
        if self.kind == "vector":
            return np.broadcast_to(self.spec, (n, 3))
        return user_values(self.spec, x, (3,), f"{self.what} callable", where)


class _Component:
    """One component of a :class:`VectorField`, as the scalar field :func:`project_dirichlet` reads."""

    def __init__(self, field: VectorField, a: int):
        self.field, self.a = field, a

    def values(self, x, chans, where):
        return np.ascontiguousarray(self.field.values(x, where)[:, self.a])


def component_field(field: VectorField, a: int) -> _Component:
    return _Component(field, a)


def merge_dirichlet(faces, supports: list, ndof: int, scalar) -> DirichletData:
    """The Dirichlet data of the three components in the component-major numbering: each component projected
    on its own faces (``supports[a]``: {(patch, face): (field, where)}) and shifted by its block."""
    nred = ndof if scalar is None else scalar.P.shape[1]
    parts = [project_dirichlet(faces, sup, ndof, scalar) for sup in supports]
    dofs = np.concatenate([p.dofs + a * nred for a, p in enumerate(parts)]).astype(np.int64)
    values = np.concatenate([p.values for p in parts])
    G = sp.block_diag([p.G if p.G is not None else sp.csr_matrix((nred, 0)) for p in parts], format="csr")
    keys = [(a, k) for a, p in enumerate(parts) for k in p.keys]
    slave_rows = np.concatenate([p.slave_rows + a * ndof for a, p in enumerate(parts)]).astype(np.int64)
    slave_values = np.concatenate([p.slave_values for p in parts])
    return DirichletData(dofs, values, G, keys, slave_rows, slave_values)


def pin_dofs(dd: DirichletData, pins: list, ndof: int, scalar) -> DirichletData:
    """``dd`` with the scalar DOFs ``pins[a]`` of each component a held at zero (their reduced unknowns; a pin
    that is a slave DOF, or already prescribed, is left as it is)."""
    nred = ndof if scalar is None else scalar.P.shape[1]
    extra = []
    for a, dofs in enumerate(pins):
        red = dofs if scalar is None else scalar.dof_master[dofs]
        extra.append(red[red >= 0] + a * nred)
    extra = np.setdiff1d(np.concatenate(extra), dd.dofs).astype(np.int64)
    return DirichletData(np.concatenate([dd.dofs, extra]), np.concatenate([dd.values, np.zeros(len(extra))]), dd.G,
                         dd.keys, dd.slave_rows, dd.slave_values)
