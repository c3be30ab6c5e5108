"""The shape of the code base: module sizes, one-way imports between packages, no import cycles inside one."""

import ast
import re
from pathlib import Path

import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("geometry", "tiling", "iga", "solvers")
# what each package may import from the others: geometry <- tiling <- iga -> solvers; solvers knows nothing
# about splines and takes only the toolkit's base exception, the progress display and the number checks from geometry
ALLOWED = {"geometry": set(), "tiling": {"geometry"}, "iga": {"geometry", "tiling", "solvers"},
           "solvers": {"geometry.errors", "geometry.progress", "geometry.numbers"}}


def _modules(pkg):
    """Every module of ``pkg`` and of its sub-packages (``tiling/vrep/union.py``), sorted."""
    return sorted((ROOT / pkg).rglob("*.py"))


def _dotted(path: Path) -> str:
    """``tiling/vrep/union.py`` -> ``tiling.vrep.union``; a package's ``__init__.py`` -> the package."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path, pkg: str = ""):
    """(target module, at module level) for every import in ``path``; relative imports resolved against the
    module's own package (``from ..tile import`` in ``tiling/vrep/x.py`` is ``tiling.tile``).

    Imports under ``if TYPE_CHECKING:`` are left out: they exist for annotations only, never at run time.
    """
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and isinstance(node.test, ast.Name) and node.test.id == "TYPE_CHECKING":
            node.body = []
    here = _dotted(path).split(".")
    package = here if path.name == "__init__.py" else here[:-1]
    top = set(id(n) for n in tree.body)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, id(node) in top) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = ".".join(package[: len(package) - node.level + 1] + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            names = [f"{base}.{a.name}" for a in node.names]  # a name, or a module of the package base
            out += [(n, id(node) in top) for n in names]
    return out


@pytest.mark.parametrize("pkg", PACKAGES)
def test_module_sizes(pkg):
    for path in _modules(pkg):
        n = len(path.read_text().splitlines())
        limit = 300 if path.relative_to(ROOT).as_posix() == "iga/heat/problem.py" else 450
        assert n <= limit, f"{path.relative_to(ROOT)} has {n} lines (limit {limit}): split it"


FUNCTION_LINES = 60  # code lines of one function, its docstring left out


def _long_functions(path: Path):
    """(name, first line, code lines) of the functions of ``path`` over :data:`FUNCTION_LINES`."""
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            doc = isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) and isinstance(
                body[0].value.value, str)
            start = body[1].lineno if doc and len(body) > 1 else body[0].lineno
            n = node.end_lineno - start + 1
            if n > FUNCTION_LINES:
                out.append((node.name, node.lineno, n))
    return out


@pytest.mark.parametrize("pkg", PACKAGES)
def test_function_sizes(pkg):
    """No function over 60 code lines; the compiled kernels (``_*kernels.py``) are exempt: their loops are
    unrolled by hand for numba, and splitting them costs speed."""
    long = [f"{path.relative_to(ROOT)}:{line} {name} ({n} lines)" for path in _modules(pkg)
            if not (path.name.startswith("_") and path.name.endswith("kernels.py"))
            for name, line, n in _long_functions(path)]
    assert not long, f"functions over {FUNCTION_LINES} code lines, split them: {long}"


@pytest.mark.parametrize("pkg", PACKAGES)
def test_imports_flow_one_way(pkg):
    others = set(PACKAGES) - {pkg}
    for path in _modules(pkg):
        for target, _ in _imports(path):
            root = target.split(".")[0]
            if root in others:
                ok = root in ALLOWED[pkg] or any(target == a or target.startswith(a + ".") for a in ALLOWED[pkg])
                assert ok, f"{path.relative_to(ROOT)} imports {target}"


def test_iga_imports_tiling_only_at_module_level():
    for path in _modules("iga"):
        for target, top in _imports(path):
            if target.split(".")[0] == "tiling":
                assert top, f"iga/{path.name} imports {target} inside a function"


@pytest.mark.parametrize("pkg", PACKAGES)
def test_no_import_cycle_inside_a_package(pkg):
    mods = [_dotted(p) for p in _modules(pkg)]
    index = {m: i for i, m in enumerate(mods)}

    def resolve(target):  # the deepest module of the package that the target names
        parts = target.split(".")
        for k in range(len(parts), 0, -1):
            if ".".join(parts[:k]) in index:
                return ".".join(parts[:k])
        return None

    rows, cols = [], []
    for path in _modules(pkg):
        me = _dotted(path)
        for target, _ in _imports(path):
            dep = resolve(target) if target.split(".")[0] == pkg else None
            if dep is not None and dep != me:
                rows.append(index[me])
                cols.append(index[dep])
    # a package's __init__ imports its modules; a module importing the package itself (``from . import x``
    # resolves to pkg.x) is the only way back, so a cycle is a strongly connected component of size > 1
    n = len(mods)
    graph = coo_matrix(([1] * len(rows), (rows, cols)), shape=(n, n))
    ncomp, labels = connected_components(graph, directed=True, connection="strong")
    sizes = {lab: [m for m, lb in zip(mods, labels) if lb == lab] for lab in set(labels)}
    cycles = [members for members in sizes.values() if len(members) > 1]
    assert not cycles, f"import cycles in {pkg}: {cycles}"


def test_no_public_name_shadows_a_module_of_its_package():
    """``import tiling.branching.paving as m`` must give the module: a function of the same name would replace it."""
    import importlib
    import pkgutil
    import types

    for pkg in ("geometry", "tiling", "iga", "solvers"):
        package = importlib.import_module(pkg)
        for mod in pkgutil.iter_modules(package.__path__):
            value = getattr(package, mod.name, None)
            assert value is None or isinstance(value, types.ModuleType), f"{pkg}.{mod.name} is {value!r}"


def test_solvers_import_without_the_spline_stack():
    """``import solvers`` takes the base exception, the progress display and the number checks, nothing of the
    splines."""
    import subprocess
    import sys

    code = "import sys, solvers; print(sorted(m for m in sys.modules if m.split('.')[0] in ('geometry', 'tiling', 'iga')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert out.stdout.strip() == str(["geometry", "geometry.errors", "geometry.numbers", "geometry.progress"]), \
        out.stdout


def test_benchmarks_write_tracked_pictures_only_through_make_figures():
    """A benchmark's pictures go to benchmarks/out/figures unless it runs with --figures (make_figures.py)."""
    for path in sorted((ROOT / "benchmarks").glob("*.py")):
        if path.name in ("make_figures.py", "_common.py"):
            continue
        text = path.read_text()
        assert '/ "docs"' not in text and "parent.parent / \"docs\"" not in text, f"{path.name} writes into docs/"


@pytest.mark.parametrize("pkg", PACKAGES)
def test_no_private_name_is_imported_across_modules(pkg):
    """A name with a leading underscore belongs to its module: what another module needs is made public (e.g.
    ``tiling.checks``).  Importing a package-private module (``from . import _fast``) is allowed."""
    modules = {_dotted(p) for name in PACKAGES for p in _modules(name)}
    found = []
    for path in _modules(pkg):
        for target, _ in _imports(path):
            last = target.rsplit(".", 1)[-1]
            if last.startswith("_") and not last.startswith("__") and target not in modules:
                found.append(f"{path.relative_to(ROOT)} imports {target}")
    assert not found, f"private names imported across modules: {found}"


_CACHE_MAKERS = {"lru_cache", "cache", "WeakKeyDictionary", "WeakValueDictionary", "OrderedDict"}


def _cache_sites(path: Path):
    """(line, what) of caches made outside :mod:`geometry.cache`: ``functools.lru_cache`` / ``cache``
    decorators on module-level functions, and module-level weak or ordered dictionaries."""
    tree = ast.parse(path.read_text())

    def name(node):
        node = node.func if isinstance(node, ast.Call) else node
        return node.attr if isinstance(node, ast.Attribute) else getattr(node, "id", "")

    out = []
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            out += [(node.lineno, f"@{name(d)} on {node.name}") for d in getattr(node, "decorator_list", [])
                    if name(d) in ("lru_cache", "cache")]
        elif isinstance(node, (ast.Assign, ast.AnnAssign)) and isinstance(node.value, ast.Call):
            inner = node.value.func if isinstance(node.value.func, ast.Call) else node.value
            if name(inner) in _CACHE_MAKERS:
                out.append((node.lineno, name(inner)))
    return out


@pytest.mark.parametrize("pkg", PACKAGES)
def test_every_cache_is_the_memo_helpers(pkg):
    """One memo (geometry.cache: bounded, keyed on values, read-only outputs, clear_caches empties it)."""
    found = [f"{path.relative_to(ROOT)}:{line} {what}" for path in _modules(pkg)
             if path.relative_to(ROOT).as_posix() != "geometry/cache.py" for line, what in _cache_sites(path)]
    assert not found, f"caches outside geometry.cache (use memo, BoundedCache or PerObject): {found}"


def test_cached_results_are_read_only_and_clear_caches_empties_them():
    import numpy as np

    from geometry import bernstein as bz
    from geometry.cache import clear_caches
    from tiling import cell_splines

    U = np.array([0, 0, 0, 0.5, 1, 1, 1.0])
    x = np.linspace(0, 1, 5)
    B = cell_splines._unit_basis(U.tobytes(), 2, x.tobytes())  # a writable array under lru_cache before
    R = cell_splines._insertion(U.tobytes(), 2, np.array([0.25]).tobytes())  # (knots, sparse matrix)
    for a in (B, bz.binomials(4), R[0], R[1].data):
        with pytest.raises(ValueError, match="read-only"):
            a.flat[0] = 7.0
    assert len(cell_splines._unit_basis.cache) >= 1
    clear_caches()
    assert len(cell_splines._unit_basis.cache) == 0 and len(bz.binomials.cache) == 0
    assert np.array_equal(cell_splines._unit_basis(U.tobytes(), 2, x.tobytes()), B)  # recomputed, the same


MODULES_AT_TOP = 15
CUT_BY_CONCEPT = PACKAGES


@pytest.mark.parametrize("pkg", CUT_BY_CONCEPT)
def test_a_package_folder_holds_at_most_fifteen_modules_at_its_top(pkg):
    """A newcomer places a module by its folder: concepts get sub-packages (tiling.implicit, tiling.sealing,
    tiling.branching, tiling.members, tiling.vrep), each folder at most ~15 modules."""
    for folder in [ROOT / pkg] + [d for d in (ROOT / pkg).rglob("*") if d.is_dir() and (d / "__init__.py").exists()]:
        mods = [p.name for p in folder.glob("*.py") if p.name != "__init__.py"]
        assert len(mods) <= MODULES_AT_TOP, f"{folder.relative_to(ROOT)} has {len(mods)} modules: {sorted(mods)}"


def test_a_zero_divisor_is_guarded_by_the_one_named_floor():
    """``max(scale, TINY)`` (geometry.numbers.TINY), not a literal 1e-300 repeated across the library."""
    found = [f"{path.relative_to(ROOT)}:{i}" for pkg in PACKAGES for path in _modules(pkg)
             if path.name != "numbers.py"
             for i, line in enumerate(path.read_text().splitlines(), 1) if re.search(r"(?<![\w.])1e-300\b", line)]
    assert not found, f"literal 1e-300 guards (use geometry.numbers.TINY): {found}"


def test_the_solvers_copy_of_the_rank_and_round_off_thresholds_is_the_toolkit_s():
    import solvers.elimination as e
    from geometry import tolerances as t

    assert (e.RANK, e.ROUNDOFF) == (t.RANK, t.ROUNDOFF)


def _kernel_modules():
    return sorted((ROOT / "iga").rglob("_*kernels.py"))


def test_no_contraction_kernel_is_specialised_to_a_term_count():
    """A form is data (iga.assembly.terms.FormTerms): the compiled contraction has one kernel factory, and no
    kernel shapes its scratch by a literal term count (heat's 7, elasticity's 9 were such counts)."""
    factories, literal_shapes = [], []
    for path in _kernel_modules():
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef) and node.name.endswith("_for"):
                factories.append(f"{path.name}:{node.name}")
            if isinstance(node, ast.Call):
                name = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", "")
                if name in ("reshape", "empty", "zeros"):
                    counts = [n.value for a in node.args for n in ast.walk(a)
                              if isinstance(n, ast.Constant) and type(n.value) is int and n.value > 4]
                    if counts:
                        literal_shapes.append(f"{path.name}:{node.lineno}: {ast.unparse(node)}")
    assert factories == ["_assembly_kernels.py:form3_for"], factories
    assert not literal_shapes, literal_shapes
