"""The shape of the code base: module sizes, one-way imports between packages, no import cycles inside one."""

import ast
from pathlib import Path

import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("geometry", "tiling", "iga", "solvers")
# what each package may import from the others: geometry <- tiling <- iga -> solvers; solvers knows nothing
# about splines and takes only the toolkit's base exception and the progress display from geometry
ALLOWED = {"geometry": set(), "tiling": {"geometry"}, "iga": {"geometry", "tiling", "solvers"},
           "solvers": {"geometry.errors", "geometry.progress"}}


def _modules(pkg):
    return sorted((ROOT / pkg).glob("*.py"))


def _imports(path: Path, pkg: str):
    """(target module, at module level) for every import in ``path``; relative imports resolved.

    Imports under ``if TYPE_CHECKING:`` are left out: they exist for annotations only, never at run time.
    """
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            node.body = []
    top = set(id(n) for n in tree.body)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, id(node) in top) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = f"{pkg}.{base}" if base else pkg
                names = [f"{base}.{a.name}" if not node.module else base for a in node.names]
            else:
                names = [f"{base}.{a.name}" for a in node.names]
            out += [(n, id(node) in top) for n in names]
    return out


@pytest.mark.parametrize("pkg", PACKAGES)
def test_module_sizes(pkg):
    for path in _modules(pkg):
        n = len(path.read_text().splitlines())
        limit = 300 if path.name == "problem.py" and pkg == "iga" else 450
        assert n <= limit, f"{pkg}/{path.name} has {n} lines (limit {limit}): split it"


@pytest.mark.parametrize("pkg", PACKAGES)
def test_imports_flow_one_way(pkg):
    others = set(PACKAGES) - {pkg}
    for path in _modules(pkg):
        for target, _ in _imports(path, pkg):
            root = target.split(".")[0]
            if root in others:
                ok = root in ALLOWED[pkg] or any(target == a or target.startswith(a + ".") for a in ALLOWED[pkg])
                assert ok, f"{pkg}/{path.name} imports {target}"


def test_iga_imports_tiling_only_at_module_level():
    for path in _modules("iga"):
        for target, top in _imports(path, "iga"):
            if target.split(".")[0] == "tiling":
                assert top, f"iga/{path.name} imports {target} inside a function"


@pytest.mark.parametrize("pkg", PACKAGES)
def test_no_import_cycle_inside_a_package(pkg):
    mods = [p.stem for p in _modules(pkg)]
    index = {m: i for i, m in enumerate(mods)}
    rows, cols = [], []
    for path in _modules(pkg):
        for target, _ in _imports(path, pkg):
            parts = target.split(".")
            if parts[0] != pkg:
                continue
            dep = parts[1] if len(parts) > 1 and parts[1] in index else "__init__"
            if dep != path.stem:
                rows.append(index[path.stem])
                cols.append(index[dep])
    # the package's __init__ imports its modules; a module importing the package itself (``from . import x``
    # resolves to pkg.x) is the only way back, so a cycle is a strongly connected component of size > 1
    n = len(mods)
    graph = coo_matrix(([1] * len(rows), (rows, cols)), shape=(n, n))
    ncomp, labels = connected_components(graph, directed=True, connection="strong")
    sizes = {lab: [m for m, lb in zip(mods, labels) if lb == lab] for lab in set(labels)}
    cycles = [members for members in sizes.values() if len(members) > 1]
    assert not cycles, f"import cycles in {pkg}: {cycles}"


def test_no_public_name_shadows_a_module_of_its_package():
    """``import tiling.branching as m`` must give the module: a function of the same name would replace it."""
    import importlib
    import pkgutil
    import types

    for pkg in ("geometry", "tiling", "iga", "solvers"):
        package = importlib.import_module(pkg)
        for mod in pkgutil.iter_modules(package.__path__):
            value = getattr(package, mod.name, None)
            assert value is None or isinstance(value, types.ModuleType), f"{pkg}.{mod.name} is {value!r}"


def test_solvers_import_without_the_spline_stack():
    """``import solvers`` takes the base exception and the progress display, nothing of the splines."""
    import subprocess
    import sys

    code = "import sys, solvers; print(sorted(m for m in sys.modules if m.split('.')[0] in ('geometry', 'tiling', 'iga')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == str(["geometry", "geometry.errors", "geometry.progress"]), out.stdout
