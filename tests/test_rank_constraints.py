"""Each rank's constraints (iga.distributed.rank_constraints) against the whole model's, without MPI: for every rank of
a partition, the rows of its own DOFs equal the serial prolongation's, with the columns matched by their
classes' smallest DOF (the key every rank numbers them by)."""

import numpy as np
import pytest
import scipy.sparse as sp

import tiling
from geometry import primitives as pr
from iga import HeatProblem
from iga.discretisation.constraints import prolongation
from iga.distributed.solve import partition
from iga.distributed.rank_constraints import class_keys, rank_constraints, ranges
from tiling import library as L


def _rows_by_key(P, keys, rows):
    """(row, key of the column's class, value) of ``P``'s ``rows``, sorted: the rows with their columns named
    by class (``keys``: per column), not by a numbering."""
    C = sp.coo_matrix(P[rows])
    C.eliminate_zeros()
    out = np.stack([C.row.astype(float), keys[C.col].astype(float), C.data], axis=1)
    return out[np.lexsort((out[:, 1], out[:, 0]))]


def _models():
    twisted = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5))
    yield "lattice", HeatProblem(tiling.regular(twisted, L.cross(), (3, 3, 2)), degree_elevation=1)
    yield "hierarchy", HeatProblem(tiling.hierarchical(pr.box((0.06, 0.06, 0.03)), L.heat_sink_t2(), (2, 2), 3))
    yield "slots", HeatProblem(tiling.hierarchical(pr.box(), L.skinned_branching(), (1, 1), 2))
    # a full ring: the last cell's tiles are glued to the first cell's across the map's seam
    yield "ring", HeatProblem(tiling.regular(pr.annulus(0.5, 1.0, 0.3, angle=2 * np.pi), L.cross(), (2, 1, 1)))


@pytest.mark.parametrize("name", ["lattice", "hierarchy", "slots", "ring"])
@pytest.mark.parametrize("ranks", [2, 5])
def test_each_ranks_rows_are_the_serial_rows(name, ranks):
    prob = dict(_models())[name]
    if name == "ring":
        from tiling.topology import seams

        assert seams(prob.model.outer)[0]  # the seam is glued (the case this model is here for)
    full = prolongation(prob.model, prob.spaces, prob.offsets)
    part = partition(prob, ranks)
    seen = np.zeros(prob.ndof, bool)
    layers = []
    for r in range(ranks):
        rc = rank_constraints(prob.model, prob.spaces, prob.offsets, part, r)
        own = np.flatnonzero(part == r)
        assert np.array_equal(rc.own_patches, own) and set(own) <= set(rc.patches)
        own_dofs = ranges(prob.offsets[own], prob.offsets[own + 1])
        assert np.array_equal(rc.rows[rc.own], own_dofs)  # the closure numbering, read back to global DOFs
        assert len(rc.rows) < prob.ndof or len(rc.patches) == len(prob.model.patches)
        mine = _rows_by_key(rc.constraints.P, rc.keys(), rc.own)
        serial = _rows_by_key(full.P, class_keys(full.dof_master, full.P.shape[1]), own_dofs)
        assert mine.shape == serial.shape and np.allclose(mine, serial, rtol=0, atol=1e-13)
        # the slave DOFs (dof_master -1) are the serial ones on the own patches
        assert np.array_equal(rc.constraints.dof_master[rc.own] < 0, full.dof_master[own_dofs] < 0)
        seen[own_dofs] = True
        layers.append(rc.layers)
    assert seen.all()  # the ranks' own DOFs cover the model
    assert max(layers) >= 1  # closures reach past the own patches


def test_a_lattice_closure_is_two_layers_and_a_fraction_of_the_model():
    """A cross tile's centre block shares its edges with four arms, so a class can span three patches: at
    most two layers of neighbours close every rank of a lattice, and the closure stays local."""
    D = pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2))
    prob = HeatProblem(tiling.regular(D, L.cross(), (6, 6, 6)), degree_elevation=1)
    part = partition(prob, 4)
    layers = []
    for r in range(4):
        rc = rank_constraints(prob.model, prob.spaces, prob.offsets, part, r)
        layers.append(rc.layers)
        assert len(rc.patches) < 0.5 * len(prob.model.patches)
    assert max(layers) == 2


class _TwoRanks:
    """The part of an MPI communicator :func:`iga.distributed.rank_setup.together` uses, as rank ``rank`` of two whose
    other rank reports ``other``."""

    def __init__(self, rank, other):
        self.rank, self.other = rank, other

    def Get_rank(self):
        return self.rank

    def allgather(self, x):
        return [x, self.other] if self.rank == 0 else [self.other, x]


def test_an_error_on_one_rank_is_raised_on_every_rank():
    from iga.errors import ProblemError
    from iga.distributed.rank_setup import together

    def fails():
        raise ProblemError("two Dirichlet conditions at odds")

    assert together(_TwoRanks(0, None), lambda: 42) == 42
    with pytest.raises(ProblemError, match="^two Dirichlet conditions at odds$"):
        together(_TwoRanks(1, None), fails)  # the rank whose patches hold the bad data: its own message
    with pytest.raises(ProblemError, match="^on MPI rank 0: two Dirichlet"):
        together(_TwoRanks(1, "two Dirichlet conditions at odds"), lambda: 42)  # the others: which rank, and why
