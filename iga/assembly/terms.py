"""A bilinear form as a table of terms: what the compiled form kernel contracts, for any number of terms.

A term couples the test functions N_i and the trial functions N_j through one coefficient field F_c on the
Gauss grid and, per parametric direction k, the derivative orders (a_k, b_k) in {0, 1} on the test and the
trial side:

    A_ij += sum_q F_c(q) prod_k d^{a_k} N_{i_k}(q_k) d^{b_k} N_{j_k}(q_k).

It is the term of the NumPy vocabulary (:func:`iga.assembly.tensor.banded_form`, whose terms carry their field
instead of an index c). Diffusion is nine such terms over six fields, a mass one term, the tangent of k(T) three
first-order terms, a block of elasticity nine; the compiled kernel
(:func:`iga.assembly.compiled.form_csr`, :class:`iga.assembly.compiled.FormAccumulator`) takes any of them.

A *symmetric* form (A = A^T: its terms closed under swapping the test and trial orders with the same field)
is contracted on half the work: only the terms whose direction-1 variant is (1, 1), (1, 0) or (0, 0) are
kept, the (0, 1) group is the mirror of the (1, 0) group and the (1, 1) and (0, 0) groups are computed on
half the direction-2 band and mirrored (:func:`iga.assembly._assembly_kernels.form_stage2`).
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np

from iga.errors import ProblemError

__all__ = ["FormTerms", "form_terms", "DIFFUSION", "RATIONAL_DIFFUSION", "MASS", "elastic_block"]

#: the six symmetric fields of a diffusion-like form, in this order: (0,0), (1,1), (2,2), (0,1), (0,2), (1,2)
SYMMETRIC_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


@dataclass(frozen=True)
class FormTerms:
    """The terms the kernel contracts (a symmetric form's kept half only).

    ``fields``: how many coefficient fields the form reads (the first axis of its field array);
    ``field`` (T,) int64: the field of each term; ``variants`` (T, 3) int64: per direction the variant
    v = 2 a + b of the term's derivative orders (a on the test side, b on the trial side);
    ``symmetric``: the form equals its transpose (module notes); ``terms``: every term as given,
    (c, ((a_1, b_1), (a_2, b_2), (a_3, b_3))), the mirrored half included (for the NumPy path);
    ``groups`` (5,) int64: the kernel's terms are ordered by direction-1 group g = 3 - v1 (0: (1,1), 1: (1,0),
    2: (0,1), 3: (0,0)), group g's terms at ``groups[g]:groups[g + 1]``.
    """

    fields: int
    field: np.ndarray
    variants: np.ndarray
    symmetric: bool
    terms: tuple
    groups: np.ndarray

    @property
    def count(self) -> int:
        """The number of terms the kernel contracts."""
        return int(len(self.field))


def _transposed(orders) -> tuple:
    return tuple((b, a) for a, b in orders)


def form_terms(terms, fields: int | None = None, symmetric: bool = False) -> FormTerms:
    """The :class:`FormTerms` of ``terms`` = [(c, ((a_1, b_1), (a_2, b_2), (a_3, b_3))), ...] (c the index of
    the term's field, a_k / b_k the derivative orders 0 or 1 on the test / trial side in direction k).

    ``fields``: the number of fields (default: the largest c + 1). ``symmetric``: declare A = A^T; checked:
    the terms must be closed under swapping every (a_k, b_k) with the same field, else :class:`ProblemError`.
    """
    terms = [(int(c), tuple((int(a), int(b)) for a, b in orders)) for c, orders in terms]
    if not terms:
        raise ProblemError("a form needs at least one term")
    for c, orders in terms:
        if c < 0 or len(orders) != 3 or any(v not in (0, 1) for pair in orders for v in pair):
            raise ProblemError(f"term ({c}, {orders}): give a field index >= 0 and three (test, trial) "
                               "derivative orders, each 0 or 1")
    n = max(c for c, _ in terms) + 1 if fields is None else int(fields)
    if n <= max(c for c, _ in terms):
        raise ProblemError(f"a term reads field {max(c for c, _ in terms)} but the form has {n} fields")
    given = tuple(terms)
    if symmetric:
        counts: dict = {}
        for term in terms:
            counts[term] = counts.get(term, 0) + 1
        odd = [t for t in counts if counts.get((t[0], _transposed(t[1])), 0) != counts[t]]
        if odd:
            raise ProblemError(f"the form is declared symmetric but term {odd[0]} has no transposed twin "
                               "(the same field with every (test, trial) order swapped)")
        terms = [t for t in terms if t[1][0] != (0, 1)]  # the (0, 1) group is the mirror of the (1, 0) one
    # the kernel's order: by direction-1 group (3 - v1: (1,1), (1,0), (0,1), (0,0)), so that each group's
    # terms are consecutive rows of the stage-3 scratch and stage 2 sums them in fused sweeps
    terms.sort(key=lambda t: 3 - (2 * t[1][0][0] + t[1][0][1]))
    field = np.array([c for c, _ in terms], np.int64)
    variants = np.array([[2 * a + b for a, b in orders] for _, orders in terms], np.int64)
    groups = np.searchsorted(3 - variants[:, 0], np.arange(5)).astype(np.int64)
    for a in (field, variants, groups):
        a.setflags(write=False)
    return FormTerms(n, field, variants, bool(symmetric), given, groups)


def _diffusion() -> FormTerms:
    """sum_rs int C_rs d_r N_i d_s N_j over the six symmetric fields of :data:`SYMMETRIC_PAIRS`."""
    terms = []
    for r, s in product(range(3), repeat=2):
        orders = tuple((int(k == r), int(k == s)) for k in range(3))
        terms.append((SYMMETRIC_PAIRS.index((min(r, s), max(r, s))), orders))
    return form_terms(terms, fields=6, symmetric=True)


#: the diffusion form (and a diagonal block of elasticity): six fields in :data:`SYMMETRIC_PAIRS` order
DIFFUSION = _diffusion()


def _rational_diffusion() -> FormTerms:
    """Diffusion in the basis N / W (:mod:`iga.discretisation.rational`): the nine second-order terms of
    :data:`DIFFUSION` on fields 0-5, the first-order terms F_r (d_r N_i N_j + N_i d_r N_j) on fields 6-8 and
    the zero-order term F_0 N_i N_j on field 9 (:func:`iga.discretisation.rational.rational_diffusion_fields`)."""
    terms = list(DIFFUSION.terms)
    for r in range(3):
        on_r = [int(k == r) for k in range(3)]  # a first derivative along r on one side
        terms += [(6 + r, tuple((d, 0) for d in on_r)), (6 + r, tuple((0, d) for d in on_r))]
    terms.append((9, ((0, 0),) * 3))
    return form_terms(terms, fields=10, symmetric=True)


#: diffusion in the NURBS basis N / W: ten fields (six second-order, three first-order, one zero-order)
RATIONAL_DIFFUSION = _rational_diffusion()


#: the mass form int F N_i N_j: one field, no derivative on either side
MASS = form_terms([(0, ((0, 0),) * 3)], fields=1, symmetric=True)


def _general() -> FormTerms:
    """sum_rs int F_rs d_r N_i d_s N_j over nine fields, F_rs at index 3 r + s (not symmetric)."""
    terms = [(3 * r + s, tuple((int(k == r), int(k == s)) for k in range(3))) for r, s in product(range(3), repeat=2)]
    return form_terms(terms, fields=9)


_GENERAL = _general()


def elastic_block(a: int, b: int) -> FormTerms:
    """The terms of block (a, b) of linear elasticity: a diagonal block is the symmetric :data:`DIFFUSION` form
    of its six fields, an off-diagonal one the nine fields F_rs (:func:`iga.assembly.compiled.elastic_into`)."""
    return DIFFUSION if a == b else _GENERAL
