"""No module-level switches: limits and progress are scoped, caches bounded, thread counts from the affinity."""

import os
import threading

import numpy as np
import pytest
from commands import iga_command
import scipy.sparse as sp

from geometry import progress, resources
from geometry.cache import BoundedCache
from geometry.errors import SplineError
from solvers.amg import AMGPreconditioner


def test_a_memory_budget_holds_inside_its_block_only_and_not_in_other_threads():
    seen = {}
    with resources.memory_budget(0.5):
        assert resources.memory_limit() == 0.5 * resources.GiB
        t = threading.Thread(target=lambda: seen.setdefault("thread", resources.memory_limit()))
        t.start()
        t.join()
        with pytest.raises(SplineError, match="needs about 1 GiB, more than the 0.5 GiB"):
            resources.check_memory(resources.GiB, "the test")
    assert resources.memory_limit() != 0.5 * resources.GiB  # the default again (the available memory)
    assert seen["thread"] != 0.5 * resources.GiB  # a thread started elsewhere keeps the default
    with pytest.raises(SplineError, match="positive number of GiB"):
        with resources.memory_budget(True):
            pass


def test_a_pipeline_limit_is_gone_after_the_run(tmp_path):
    from iga.errors import ToolkitError
    from iga.app.pipeline import heat_sink_config, run_pipeline

    cfg = {**heat_sink_config("vertical", levels=1, out=str(tmp_path / "out")), "limits": {"max_memory_gib": 1e-6}}
    with pytest.raises(ToolkitError, match="more than the 1e-06 GiB"):
        run_pipeline(cfg, tmp_path)
    assert resources.memory_limit() > 1e-3 * resources.GiB and not (tmp_path / "out").exists()


def test_progress_is_scoped_to_its_block():
    assert not progress.active()
    with progress.enabled(True):
        assert progress.active()
        with progress.enabled(False):
            assert not progress.active() and progress.bar([1, 2, 3]) == [1, 2, 3]
        assert progress.active()
    assert not progress.active()


def test_the_core_count_is_the_affinity_mask():
    if not hasattr(os, "sched_getaffinity"):
        pytest.skip("no CPU affinity on this platform")
    assert resources.usable_cores() == len(os.sched_getaffinity(0))


def test_a_bounded_cache_keeps_its_size():
    cache = BoundedCache(3)
    made = []
    for k in [1, 2, 3, 1, 4, 5, 1]:
        cache.get(k, lambda k=k: made.append(k) or k)
    assert len(cache) == 3 and made == [1, 2, 3, 4, 5] and 1 in cache and 2 not in cache
    with pytest.raises(ValueError):
        BoundedCache(0)


def test_amg_leaves_nothing_on_the_callers_matrix():
    n = 400
    A = sp.diags([-np.ones(n - 1), 2.0 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1], format="csr")
    data = A.data.copy()
    AMGPreconditioner(A, max_coarse=10)
    assert not hasattr(A, "rho") and np.array_equal(A.data, data)
    M = AMGPreconditioner(A, max_coarse=10, overwrite=True)
    assert not hasattr(A, "rho") and M.scaled.rho > 0
    assert np.allclose(A.diagonal(), 1.0)  # overwrite: the caller's values hold S A S, as documented


def test_one_definition_of_the_same_space():
    from geometry.tolerances import SAME_KNOT, same_knots, same_space

    U = np.r_[0, 0, 0, 0.3, 1, 1, 1]
    assert same_knots(U, U * 2 + 5)  # normalised: the same space on another interval
    assert same_knots(U, U + np.r_[0, 0, 0, 0.4 * SAME_KNOT, 0, 0, 0])
    assert not same_knots(U, U + np.r_[0, 0, 0, 3 * SAME_KNOT, 0, 0, 0]) and not same_knots(U, U[1:])
    assert same_space([(U, 2), (U, 2)], [(U, 2), (U * 3, 2)]) and not same_space([(U, 2)], [(U, 3)])


def test_block_assembly_names_offsets_that_do_not_match_the_spaces():
    from iga.assembly.tensor import block_diagonal_csr
    from iga.errors import ProblemError

    class Pattern:  # what block_diagonal_csr reads of a CSR pattern
        n = 2
        indptr = np.array([0, 1, 2])
        indices = np.array([0, 1], np.int32)

    with pytest.raises(ProblemError, match="a block starts at 3, expected 2"):
        block_diagonal_csr([(0, Pattern, np.ones(2)), (3, Pattern, np.ones(2))], 5)
    with pytest.raises(ProblemError, match="end at 4, but the system has 6"):
        block_diagonal_csr([(0, Pattern, np.ones(2)), (2, Pattern, np.ones(2))], 6)


def test_a_tile_branch_face_with_a_bad_box_is_one_tiling_error_and_a_bug_stays_a_bug(monkeypatch):
    from tiling import library
    from tiling.errors import TilingError
    from tiling.tile import BranchFace, _rect

    tile = library.cross()
    with pytest.raises(TilingError, match="cannot extract the face"):
        _rect(tile, BranchFace(0, "wmax", box=((0.0, 0.5), (0.0, 0.5), (0.0, 0.5), (0, 1))), "branch-out 0")
    monkeypatch.setattr(BranchFace, "surface", lambda self, t: 1 / 0)  # a programming error is not hidden
    with pytest.raises(ZeroDivisionError):
        _rect(tile, BranchFace(0, "wmax"), "branch-out 0")


def test_solutions_print_in_one_line_and_the_demo_takes_quiet_after_its_name(tmp_path):

    from geometry import primitives as pr
    from iga import ElasticityProblem, HeatProblem

    s = HeatProblem(pr.box()).dirichlet("umin", 0.0).dirichlet("umax", 1.0).solve()
    assert repr(s).startswith("Solution(1 patches, 8 DOFs") and "\n" not in repr(s)
    e = ElasticityProblem(pr.box(), youngs=1.0, poisson=0.3).dirichlet("umin", 0.0).traction("umax", [1, 0, 0]).solve()
    assert repr(e).startswith("ElasticSolution(1 patches, 24 DOFs") and "strain energy" in repr(e)
    out = iga_command("demo", "heat-sink", "--quiet", "--help")
    assert out.returncode == 0 and "--quiet" in out.stdout


def test_paused_gc_restores_the_collector_as_it_found_it():
    import gc

    from geometry.resources import paused_gc

    assert gc.isenabled()
    with paused_gc():
        assert not gc.isenabled()
        with paused_gc():  # a builder calling another: still paused when the inner one ends
            pass
        assert not gc.isenabled()
    assert gc.isenabled()
    with pytest.raises(ValueError):
        with paused_gc():
            raise ValueError("a failed build")
    assert gc.isenabled()  # restored on the error too
    gc.disable()
    try:
        with paused_gc():
            pass
        assert not gc.isenabled()  # the caller had it off: left off
    finally:
        gc.enable()


def test_pavings_build_with_the_collector_paused_and_leave_it_on(monkeypatch):
    import gc

    import tiling
    from geometry import primitives as pr
    from tiling import library as L
    from tiling.microstructure import Microstructure

    seen = []
    real = Microstructure.build.__func__

    def spy(cls, *args, **kwargs):
        seen.append(gc.isenabled())
        return real(cls, *args, **kwargs)

    monkeypatch.setattr(Microstructure, "build", classmethod(spy))
    ms = tiling.regular(pr.box(), L.cross(), (2, 1, 1))
    assert seen == [False] and gc.isenabled() and len(ms.patches) == 14
