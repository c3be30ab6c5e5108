"""Lint (ruff: pyflakes and bugbear) and the compiled kernels run as plain Python."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_ruff_finds_nothing():
    pytest.importorskip("ruff", reason="ruff is in the test extra: pip install -e '.[test]'")
    out = subprocess.run([sys.executable, "-m", "ruff", "check", "geometry", "tiling", "iga", "solvers", "tests",
                          "benchmarks"], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


@pytest.mark.slow
@pytest.mark.long
def test_compiled_kernels_as_plain_python():
    # numba compiles the kernels and privatises variables inside prange loops; run as plain Python
    # (NUMBA_DISABLE_JIT=1) the same kernels must give the same results, so that a loop variable that
    # only works by privatisation cannot hide, and coverage sees the kernels' lines
    pytest.importorskip("numba", reason="the compiled paths need numba (test extra)")
    env = {**os.environ, "NUMBA_DISABLE_JIT": "1"}
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "tests/test_fast_paths.py",
                          "tests/test_elasticity.py",  # the elastic block, mirror and vector-structure kernels
                          "tests/test_bernstein_products.py",  # the Bernstein product kernel
                          "-k", "(compiled or in_place or fold or mirrored) and not "
                          "high_degree_surfaces"], cwd=ROOT,  # (that composition takes minutes as plain Python)
                         env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout[-4000:] + out.stderr[-2000:]
    assert " passed" in out.stdout and "skipped" not in out.stdout.splitlines()[-1], out.stdout[-500:]
