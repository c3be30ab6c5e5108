import os
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))


def pytest_configure(config):
    """Under pytest-xdist each worker computes on one thread (numba's kernels and BLAS), as the workers already
    use every core between them: two workers of two threads each on two cores spent a fifth of their time
    waiting for each other's threads.  Tests marked ``all_threads`` (the compiled kernels against their NumPy
    references, where a race between threads would show) run on every thread numba and BLAS have."""
    if hasattr(config, "workerinput"):
        import numba
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)
        numba.set_num_threads(1)


@pytest.fixture(autouse=True)
def _threads_for_marked_tests(request):
    """Every thread for a test marked ``all_threads`` (see :func:`pytest_configure`), one again after it."""
    if request.node.get_closest_marker("all_threads") is None or not hasattr(request.config, "workerinput"):
        yield
        return
    import numba
    from threadpoolctl import threadpool_limits

    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    with threadpool_limits(os.cpu_count()):
        yield
    numba.set_num_threads(1)


def pytest_collection_modifyitems(config, items):
    """Run the tests marked ``long`` first and those marked ``last`` last (the order is otherwise kept): with
    pytest-xdist the workers then share out the short tests at the end instead of one of them finishing a long
    test alone, and a test that reruns others in a child process finds numba's kernels cached (compiling them
    cold in the child doubled its time)."""
    items.sort(key=lambda item: (item.get_closest_marker("last") is not None,
                                 item.get_closest_marker("long") is None))
