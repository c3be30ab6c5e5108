"""Parallel VTU output (iga.write_pieces): pieces per rank and the .pvtu index, read back as one dataset.

The MPI run itself is in tests/test_mpi.py (skipped where petsc4py is absent); here the ranks are played one
after the other in this process by a stand-in communicator, so the pieces and the index are checked on every
CI run against the serial file.
"""

import numpy as np
import pytest
from scipy.spatial import cKDTree

import tiling
from geometry import primitives as pr
from iga import HeatProblem, ProblemError, write_pieces, write_vtu
from tiling import library as L


class _Ranks:
    """The communicator calls write_pieces makes, for ranks played in turn (the last one played is rank 0)."""

    def __init__(self, rank, size):
        self.rank, self.size = rank, size

    def Get_rank(self):
        return self.rank

    def Get_size(self):
        return self.size

    def allreduce(self, value):
        return value * self.size

    def Barrier(self):
        pass


@pytest.fixture(scope="module")
def solved():
    ms = tiling.regular(pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5)),
                        L.cross(), (2, 2, 1))
    return HeatProblem(ms, degree_elevation=1).dirichlet("umin", 0.0).neumann("umax", 1.0).solve()


@pytest.mark.parametrize("size", [2, 3])
def test_pieces_welded_give_the_serial_file(solved, tmp_path, size):
    import meshio
    import pyvista as pv

    n = len(solved.problem.model.patches)
    solved.record.partition = np.arange(n) * size // n  # consecutive blocks of patches, as the RCM cut makes
    try:
        for rank in reversed(range(size)):  # rank 0 last: it writes the index once every piece is there
            path = write_pieces(tmp_path / "sink.pvtu", solved, _Ranks(rank, size), samples=2)
    finally:
        solved.record.partition = None
    assert sorted(p.name for p in tmp_path.glob("sink_*.vtu")) == [f"sink_{r}.vtu" for r in range(size)]
    pieces = [meshio.read(tmp_path / f"sink_{r}.vtu") for r in range(size)]  # a second reader, piece by piece
    serial = pv.read(write_vtu(tmp_path / "serial.vtu", solved, samples=2))
    par = pv.read(path)
    assert par.n_cells == serial.n_cells == sum(len(m.cells_dict["hexahedron"]) for m in pieces)
    assert par.n_points > serial.n_points  # the pieces' shared points are in both
    welded = par.clean(tolerance=1e-9 * serial.length)
    dist, match = cKDTree(serial.points).query(welded.points)
    assert welded.n_points == serial.n_points and dist.max() < 1e-9 * serial.length
    assert len(np.unique(match)) == serial.n_points
    # continuous fields (temperature, channels) everywhere; fields averaged over the patches at a point (the
    # heat flux) away from the rank boundaries, where a piece averages only its own patches
    shared = sum(cKDTree(m.points).query(welded.points)[0] < 1e-9 * serial.length for m in pieces) > 1
    assert 0 < shared.sum() < 0.5 * len(shared)
    for name in serial.point_data.keys():
        a, b = np.asarray(welded.point_data[name]), np.asarray(serial.point_data[name])[match]
        where = ~shared if name == "heat_flux" else slice(None)
        assert np.allclose(a[where], b[where], rtol=1e-10, atol=1e-12 * np.abs(b).max(), equal_nan=True), name
    assert set(serial.cell_data.keys()) <= set(par.cell_data.keys())


def test_write_pieces_refuses_a_serial_solution_and_a_wrong_suffix(solved, tmp_path):
    with pytest.raises(ProblemError, match="distributed solve.*write_vtu"):
        write_pieces(tmp_path / "a.pvtu", solved, _Ranks(0, 2))
    with pytest.raises(ProblemError, match=r"\.pvtu"):
        write_pieces(tmp_path / "a.vtu", solved, _Ranks(0, 2))
    assert not list(tmp_path.iterdir())  # nothing half-written


def test_a_rank_that_cannot_write_leaves_no_piece_and_no_index(solved, tmp_path):
    class _OtherRankFailed(_Ranks):
        def allreduce(self, value):
            return value * self.size - 1  # one other rank reports that its piece could not be written

    n = len(solved.problem.model.patches)
    solved.record.partition = np.arange(n) * 2 // n
    try:
        with pytest.raises(ProblemError, match=r"1 of 2 ranks could not write their pieces of sink\.pvtu"):
            write_pieces(tmp_path / "sink.pvtu", solved, _OtherRankFailed(0, 2), samples=1)
    finally:
        solved.record.partition = None
    assert not list(tmp_path.iterdir())  # this rank's piece removed, no index
