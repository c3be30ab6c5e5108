"""The tests marked ``kernel_sensitive`` pass under a second OpenBLAS kernel as well as under the machine's own.

A geometric decision (keep a bridge or give it up as folded, pick the nearest trimming face, resolve
collisions in turn) or an exactness claim across thread counts must not rest on the last bits of a product:
OpenBLAS picks its kernel by CPU (SkylakeX on AVX-512 machines, Haswell on others), and the kernels round
differently.  This test runs those tests again in a child process under another kernel, so the class cannot
come back unseen: Sandybridge (AVX, which every x86-64 CPU the toolkit runs on has) where the machine does not
pin a kernel itself; where it does (``OPENBLAS_CORETYPE`` set for a CPU whose autodetected kernel is unsafe,
which must then be left alone) or the CPU has no AVX, the child runs with BLAS on one thread instead, which
changes how the sums of a product are split as well.
"""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _second_kernel() -> dict:
    """The environment changes of the second run (module notes)."""
    try:
        avx = " avx " in f" {Path('/proc/cpuinfo').read_text().replace(chr(10), ' ')} "
    except OSError:
        avx = False
    if not os.environ.get("OPENBLAS_CORETYPE") and avx:
        return {"OPENBLAS_CORETYPE": "Sandybridge"}
    return {"OPENBLAS_NUM_THREADS": "1"}


@pytest.mark.slow
@pytest.mark.last
def test_kernel_sensitive_tests_pass_under_a_second_blas_kernel():
    change = _second_kernel()
    env = dict(os.environ, **change)
    env.pop("PYTEST_XDIST_WORKER", None)
    env.pop("PYTEST_XDIST_TESTRUNUID", None)
    # the modules that mark tests kernel_sensitive (collecting the whole suite to deselect it took 10-15 s)
    files = [str(p.relative_to(ROOT)) for p in sorted((ROOT / "tests").glob("test_*.py"))
             if p.name != Path(__file__).name and "mark.kernel_sensitive" in p.read_text()]
    assert files, "no module marks a test kernel_sensitive"
    # on every core: run last, the child has them to itself once the other workers are done
    workers = str(min(os.cpu_count() or 1, 4))
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", workers,
                          "-m", "kernel_sensitive", *files], cwd=ROOT, env=env, capture_output=True, text=True,
                         timeout=900)
    tail = "\n".join(run.stdout.splitlines()[-30:])
    assert run.returncode == 0, f"under {change}:\n{tail}\n{run.stderr[-2000:]}"
    assert " passed" in tail and "failed" not in tail.split("\n")[-1]
