"""One entry for a form's operator on one space: the compiled form kernel where it pays, NumPy otherwise.

A new term of a PDE is a :class:`iga.assembly.terms.FormTerms` and its coefficient fields on the Gauss grid;
:func:`form_data` contracts it by the compiled kernel (:func:`iga.assembly.compiled.form_csr`) for groups of
patches with enough work (:func:`iga.assembly.compiled.applies`) and by the NumPy reference
(:func:`iga.assembly.tensor.banded_form`) otherwise; both give the data on :func:`iga.assembly.tensor.pattern`'s
entries, equal to rounding (``tests/test_fast_paths.py``).
"""

from __future__ import annotations

import numpy as np

from iga.assembly import compiled
from iga.assembly.tensor import CSRPattern, banded_form, banded_to_csr_data, pattern
from iga.assembly.terms import FormTerms, form_terms
from iga.discretisation.space import TensorSpace
from iga.errors import ProblemError

__all__ = ["form_data", "terms_data"]


def form_data(space: TensorSpace, C: np.ndarray, form: FormTerms, pat: CSRPattern | None = None) -> np.ndarray:
    """CSR data (P, nnz) of ``form`` on P patches sharing ``space``: C (form.fields, P) + qshape its
    coefficient fields on the Gauss grid (quadrature weights and |J| included); entries in the order of
    ``pat`` (default :func:`iga.assembly.tensor.pattern` of the space)."""
    C = np.asarray(C, float)
    if C.ndim != 2 + space.dim or C.shape[0] != form.fields or C.shape[2:] != space.qshape:
        raise ProblemError(f"a form of {form.fields} fields on a space of Gauss grid {space.qshape} takes fields "
                           f"(fields, patches) + grid; got {C.shape}")
    if space.dim == 3 and compiled.applies(space, C.shape[1], terms=form.count):
        return compiled.form_csr(space, C, form)[1]
    if any(orders[space.dim:] != ((0, 0),) * (3 - space.dim) for _, orders in form.terms):
        raise ProblemError(f"the form differentiates along a direction a {space.dim}-D space does not have")
    pat = pat or pattern(space)
    return banded_to_csr_data(space, banded_form(space, [(C[c], orders[:space.dim]) for c, orders in form.terms]),
                              pat)


def terms_data(space: TensorSpace, terms, pat: CSRPattern | None = None) -> np.ndarray:
    """CSR data (P, nnz) of a form written as terms [(F, orders)] of :func:`iga.assembly.tensor.banded_form`'s
    vocabulary (F broadcasting to (P,) + qshape; orders ((a_k, b_k),) per direction): the terms of equal orders
    summed into one field, then :func:`form_data` (compiled for groups with enough work).  How the NURBS basis's
    rewritten forms (:func:`iga.discretisation.rational.rational_form`) reach the compiled kernel."""
    merged: dict = {}
    for F, orders in terms:
        key = tuple((int(a), int(b)) for a, b in orders) + ((0, 0),) * (3 - len(orders))
        merged[key] = merged[key] + F if key in merged else np.asarray(F, float)
    if not merged:
        raise ProblemError("a form needs at least one term")
    keys = list(merged)
    shape = np.broadcast_shapes(*(np.shape(F) for F in merged.values()))
    C = np.stack([np.broadcast_to(merged[k], shape) for k in keys])
    return form_data(space, C, form_terms([(c, k) for c, k in enumerate(keys)], fields=len(keys)), pat)
