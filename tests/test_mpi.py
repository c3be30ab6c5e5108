"""PETSc backend and distributed runs (extra ``[mpi]``): skipped, with the reason, where petsc4py is absent.

The distributed checks run ``mpiexec -n 2`` on small models and compare the temperatures with the serial
solve to the solver tolerance.
"""

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

import solvers
import tiling
from geometry import primitives as pr
from iga import ElasticityProblem, HeatProblem
from iga.distributed.solve import launch_env, mpiexec
from tiling import library as L

petsc4py = pytest.importorskip("petsc4py", reason="petsc4py is not installed (extra [mpi]); the PETSc backend and "
                               "the distributed runs are not checked")
pytest.importorskip("mpi4py", reason="mpi4py is not installed (extra [mpi])")
MPIEXEC = mpiexec()
if MPIEXEC is None:
    pytest.skip("no mpiexec beside this Python or on PATH (pip install mpich, or apt install openmpi-bin)",
                allow_module_level=True)

ROOT = Path(__file__).resolve().parent.parent

SCRIPT = textwrap.dedent("""
    import json, sys
    import numpy as np
    import tiling
    from geometry import primitives as pr
    from iga import HeatProblem
    from iga.distributed.solve import is_root
    from tiling import library as L

    kind, out = sys.argv[1], sys.argv[2]
    if kind == "lattice":
        D = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5))
        p = (HeatProblem(tiling.regular(D, L.cross(), (3, 2, 2)), conductivity=20.0, degree_elevation=1)
             .dirichlet("umin", 80.0).robin("umax", 50.0, 20.0).neumann("vmin", 500.0))
    elif kind == "sink":
        ms = tiling.hierarchical(pr.box((0.06, 0.06, 0.03)), L.heat_sink_t2(), (2, 2), levels=2)
        p = HeatProblem(ms, conductivity=200.0, source=1e5).dirichlet("branch-in", 60.0).robin("exterior", 40.0, 20.0)
    elif kind == "ring":  # a full annulus: tiles glued across the map's seam, on different ranks
        ms = tiling.regular(pr.annulus(0.5, 1.0, 0.3, angle=2 * np.pi), L.cross(), (2, 1, 1))
        p = HeatProblem(ms, conductivity=5.0).dirichlet("vmin", 80.0).robin("vmax", 10.0, 20.0)
    elif kind == "slot":  # Dirichlet slot faces meet the parent's branch-out face inside an element
        ms = tiling.hierarchical(pr.box(), L.skinned_branching(), (1, 1), 2)
        ms.tags["rest"] = [f for f in ms.tags["boundary"] if f not in set(ms.tags["branch-in"])]
        p = HeatProblem(ms, conductivity=3.0, source=2.0).dirichlet("branch-in", 10.0).dirichlet("rest", 0.0)
    elif kind in ("apart", "apart-robin"):  # two crosses without the interface between them
        ms = tiling.regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (2, 1, 1))
        ms.interfaces[:] = [i for i in ms.interfaces if ms.patches[i.a[0]].tile == ms.patches[i.b[0]].tile]
        p = HeatProblem(ms).dirichlet("umin", 0.0)
        p = p.neumann("umax", 1.0) if kind == "apart" else p.robin("umax", 1.0, 1.0)
    else:
        p = HeatProblem(pr.box(degrees=(2, 2, 2), elements=(4, 4, 4))).dirichlet("boundary", 0.0)
    s = p.solve(solver=sys.argv[3] if len(sys.argv) > 3 else "petsc", tol=1e-12)
    if is_root():
        tag = {"lattice": "umin", "sink": "branch-in", "slot": "branch-in", "ring": "vmin"}.get(kind, "umax")
        json.dump({"u": s.u.tolist(), "balance": s.info["balance"]["relative_error"], "method": s.info["solver"]["method"],
                   "flux": s.flux(tag), "route": s.info["solver"].get("constraints"),
                   "components": [s.info["components"][k] for k in ("count", "idle")],
                   "free": s.info["free_dofs"], "prescribed": s.info["constraints"]["prescribed"]}, open(out, "w"))
""")


_SERIAL: dict = {}  # the serial reference of each (script, case), solved once per test process


def _serial(tmp_path, script: str, *args) -> dict:
    """The serial direct solve of ``script``'s case ``args`` (its JSON), run in this process (no MPI launched:
    the plain serial path) and kept for the other rank counts of the same case."""
    import runpy

    key = (script, *map(str, args))
    if key not in _SERIAL:
        path, out = tmp_path / "serial.py", tmp_path / "serial.json"
        path.write_text(script)
        argv = sys.argv
        sys.argv = [str(path), str(args[0]), str(out), *map(str, args[1:])]
        try:
            runpy.run_path(str(path), run_name="__main__")
        finally:
            sys.argv = argv
        _SERIAL[key] = json.loads(out.read_text())
    return _SERIAL[key]


def _mpi(tmp_path, ranks, *args):
    script = tmp_path / "run.py"
    script.write_text(SCRIPT)
    return subprocess.run([MPIEXEC, "-n", str(ranks), sys.executable, str(script), *map(str, args)],
                          capture_output=True, text=True, cwd=ROOT, timeout=600, env=launch_env())


def test_the_serial_petsc_backend_solves_like_the_direct_solver():
    rng = np.random.default_rng(0)
    B = sp.random(200, 200, density=0.02, random_state=1)
    A = (B @ B.T + 200 * sp.identity(200)).tocsr()
    b = rng.standard_normal(200)
    x, info = solvers.solve(A, b, method="petsc", tol=1e-12)
    assert info.method.startswith("petsc") and info.iterations > 0
    assert np.abs(x - solvers.solve(A, b, method="direct")[0]).max() < 1e-9 * np.abs(x).max()


@pytest.mark.parametrize("kind,ranks,route", [("lattice", 1, "per rank"), ("lattice", 2, "per rank"),
                                              ("sink", 2, "per rank"), ("lattice", 4, "per rank"),
                                              ("sink", 4, "per rank"), ("slot", 2, "replicated"),
                                              ("apart-robin", 2, "per rank"), ("ring", 3, "per rank")])
def test_ranks_give_the_serial_temperatures(tmp_path, kind, ranks, route):
    """Each rank builds the constraints its patches read (iga.distributed.rank_constraints), except where Dirichlet slot
    faces tie unknowns of the whole model together (the replicated route): temperatures, fluxes, the
    unknowns counted and the components found equal the serial solve's."""
    out = _mpi(tmp_path, ranks, kind, tmp_path / "mpi.json")
    assert out.returncode == 0, out.stderr[-3000:]
    par = json.loads((tmp_path / "mpi.json").read_text())
    assert f"{ranks} ranks" in par["method"]  # one rank under mpiexec takes the same distributed path
    assert par["route"] == route
    ser = _serial(tmp_path, SCRIPT, kind, "direct")
    u, v = np.array(par["u"]), np.array(ser["u"])
    assert np.abs(u - v).max() < 1e-8 * np.abs(v).max()
    assert par["balance"] < 1e-9 and par["flux"] == pytest.approx(ser["flux"], rel=1e-8, abs=1e-12)
    assert par["free"] == ser["free"] and par["components"] == ser["components"]
    assert par["prescribed"] == ser["prescribed"]


ELASTIC = textwrap.dedent("""
    import json, sys
    import numpy as np
    import tiling
    from geometry import primitives as pr
    from iga import ElasticityProblem, HeatProblem
    from iga.distributed.solve import is_root
    from tiling import library as L

    kind, out, solver = sys.argv[1], sys.argv[2], sys.argv[3]
    if kind == "lattice":  # a twisted cross lattice clamped at one end, pulled and weighed, on springs
        D = pr.twisted(pr.box((3.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(1.5, 0.5))
        ms = tiling.regular(D, L.cross(), (3, 2, 2))
        p = (ElasticityProblem(ms, 70e9, 0.3, degree_elevation=1).dirichlet("umin", 0.0).traction("umax", (1e6, 0.0, -2e5))
             .body_force((0.0, 0.0, -2.7e4)).spring(lambda x: x[:, 2] >= 1.0 - 1e-9, [0.0, 0.0, 1e8], name="bed")
             .point_load((1.5, 0.5, 0.25), (0.0, 3e3, 0.0)))
        heat = HeatProblem(ms, conductivity=200.0, degree_elevation=1).dirichlet("umin", 0.0).neumann("umax", 1e3)
        tag = "umin"
    elif kind == "held-load":  # a load on a held component of the faces at u = 1: refused where they are assembled
        ms = tiling.regular(pr.box((3.0, 1.0, 1.0)), L.cross(), (3, 1, 1))
        p = ElasticityProblem(ms, 70e9, 0.3).dirichlet("umin", 0.0).dirichlet("umax", 0.0, "z").traction(
            "umax", (0.0, 0.0, -1e4))
        heat, tag = None, "umin"
    else:  # a two-level sink: refinement-matrix constraints across its branch faces, held on its branch-in face
        ms = tiling.hierarchical(pr.box((0.06, 0.06, 0.03)), L.heat_sink_t2(), (2, 2), levels=2)
        p = ElasticityProblem(ms, 70e9, 0.33).dirichlet("branch-in", 0.0).body_force((1e5, 0.0, -2e5))
        heat = HeatProblem(ms, conductivity=200.0).dirichlet("branch-in", 0.0).robin("exterior", 40.0, 20.0)
        tag = "branch-in"
    s = p.solve(solver=solver, tol=1e-12)
    h = heat.solve(solver=solver, tol=1e-10)
    if is_root():
        json.dump({"u": s.u.tolist(), "balance": s.info["work"]["relative_error"],
                   "method": s.info["solver"]["method"], "iterations": s.info["solver"]["iterations"],
                   "heat_iterations": h.info["solver"]["iterations"], "reaction": s.reaction(tag).tolist(),
                   "springs": s.reaction("bed").tolist() if kind == "lattice" else [],
                   "free": s.info["free_dofs"]}, open(out, "w"))
""")


@pytest.mark.parametrize("kind,ranks", [("lattice", 2), ("lattice", 4), ("sink", 2)])
def test_ranks_give_the_serial_displacements(tmp_path, kind, ranks):
    """Each rank assembles its own patches' stiffness and loads (the springs and point loads cut to its DOFs);
    GAMG gets the rigid modes: displacements, reactions, springs' forces and the work balance equal the serial
    direct solve's."""
    script = tmp_path / "elastic.py"
    script.write_text(ELASTIC)

    def run(n, solver, name):
        out = subprocess.run([MPIEXEC, "-n", str(n), sys.executable, str(script), kind, str(tmp_path / name), solver],
                             capture_output=True, text=True, cwd=ROOT, timeout=600, env=launch_env())
        assert out.returncode == 0, out.stderr[-3000:]
        return json.loads((tmp_path / name).read_text())

    par, ser = run(ranks, "petsc", "mpi.json"), _serial(tmp_path, ELASTIC, kind, "direct")
    assert f"{ranks} ranks" in par["method"] and par["free"] == ser["free"]
    u, v = np.array(par["u"]), np.array(ser["u"])
    assert np.abs(u - v).max() < 1e-8 * np.abs(v).max()
    assert par["balance"] < 1e-8
    assert np.allclose(par["reaction"], ser["reaction"], rtol=1e-7, atol=1e-7 * np.abs(ser["reaction"]).max())
    assert np.allclose(par["springs"], ser["springs"], rtol=1e-7, atol=1e-3)
    assert 0 < par["iterations"] < 300 and par["heat_iterations"] > 0


def test_a_bad_load_on_one_ranks_faces_is_refused_on_every_rank(tmp_path):
    # the faces at u = 1 are assembled by the last rank alone; the others must not wait for it in a collective
    script = tmp_path / "elastic.py"
    script.write_text(ELASTIC)
    out = subprocess.run([MPIEXEC, "-n", "2", sys.executable, str(script), "held-load", str(tmp_path / "x.json"),
                          "petsc"], capture_output=True, text=True, cwd=ROOT, timeout=300, env=launch_env())
    assert out.returncode != 0 and not (tmp_path / "x.json").exists()
    assert out.stderr.count("a load on a prescribed component only changes the reaction") == 2
    assert "on MPI rank" in out.stderr  # the rank without those faces names the one that refused


def test_petsc_elasticity_is_given_the_rigid_modes():
    """GAMG with the six rigid modes as its near-nullspace, against the same system without them: the modes
    are what make its coarse spaces represent rotations (here 278 -> 45 iterations)."""
    import iga.discretisation.system as system

    D = pr.twisted(pr.box((3.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(1.5, 0.5))
    ms = tiling.regular(D, L.cross(), (6, 2, 2))
    seen = {}
    solve = system.solvers.solve

    def spy(A, b, method, **options):
        seen.update(A=A.copy(), b=b.copy(), options=options)
        return solve(A, b, method=method, **options)

    system.solvers.solve = spy
    try:
        s = (ElasticityProblem(ms, 70e9, 0.3, degree_elevation=1).dirichlet("umin", 0.0)
             .traction("umax", (1e6, 0.0, -2e5)).solve(solver="petsc", tol=1e-10))
    finally:
        system.solvers.solve = solve
    assert seen["options"]["near_nullspace"].shape == (seen["A"].shape[0], 6)
    _, plain = solvers.solve(seen["A"], seen["b"], method="petsc", tol=1e-10)
    direct = ElasticityProblem(ms, 70e9, 0.3, degree_elevation=1).dirichlet("umin", 0.0).traction(
        "umax", (1e6, 0.0, -2e5)).solve(solver="direct")
    assert np.abs(s.u - direct.u).max() < 1e-7 * np.abs(direct.u).max()
    assert s.info["solver"]["iterations"] < plain.iterations / 3


def test_a_floating_piece_is_refused_on_every_rank(tmp_path):
    out = _mpi(tmp_path, 2, "apart", tmp_path / "x.json")
    assert out.returncode != 0 and not (tmp_path / "x.json").exists()
    # every rank found the same two pieces from its own patches and refused the same one
    assert out.stderr.count("falls apart into 2 connected pieces and 1 of them float") == 2


def _welded_like(par, serial, field: str):
    """The pieces ``par`` (a .pvtu read by VTK) welded: the serial file's points and cells, and its ``field``
    to 1e-8 at each point's serial twin; returns the welded grid."""
    from scipy.spatial import cKDTree

    welded = par.clean(tolerance=1e-9 * serial.length)  # (an absolute tolerance for unstructured grids)
    assert welded.n_points == serial.n_points and welded.n_cells == serial.n_cells
    dist, match = cKDTree(serial.points).query(welded.points)  # each welded point's serial twin
    assert dist.max() < 1e-9 * serial.length and len(np.unique(match)) == serial.n_points
    v, vs = welded.point_data[field], serial.point_data[field][match]
    assert np.abs(v - vs).max() < 1e-8 * np.abs(vs).max()
    return welded


def test_mpiexec_iga_run_writes_one_result(tmp_path):
    cfg = tmp_path / "sink.toml"
    cfg.write_text(textwrap.dedent("""
        [map]
        primitive = "box"
        args = {size = [0.06, 0.06, 0.03]}
        [tile]
        library = "heat_sink_t1"
        [paving]
        scheme = "hierarchical"
        counts = [2, 2]
        levels = 2
        [material]
        conductivity = 200.0
        [[bc]]
        kind = "dirichlet"
        tag = "branch-in"
        value = 60.0
        [[bc]]
        kind = "robin"
        tag = "exterior"
        h = 40.0
        ambient = 20.0
        [solver]
        method = "petsc"
        tol = 1e-12
        [output]
        dir = "out"
        png = false
    """))
    iga = str(Path(sys.executable).parent / "iga")
    out = subprocess.run([MPIEXEC, "-n", "2", iga, "run", str(cfg)], capture_output=True, text=True, timeout=600,
                         env=launch_env())
    assert out.returncode == 0, out.stderr[-3000:]
    assert out.stdout.count("balance error") == 1  # rank 0 reports, once
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["solver"]["ranks"] == 2 and summary["energy_balance_error"] < 1e-9
    assert summary["connected_pieces"] == 1  # the paving is one coupled piece
    # one VTU piece per rank and the .pvtu index, read as one dataset by VTK (pyvista) and piece by piece by
    # meshio; welded, it has the serial file's points and temperatures
    out_dir = tmp_path / "out"
    name = Path(summary["files"]["vtu"]).stem
    assert summary["files"]["vtu"].endswith(".pvtu") and sorted(p.name for p in out_dir.glob(f"{name}_*.vtu")) == [
        f"{name}_0.vtu", f"{name}_1.vtu"]
    import meshio
    import pyvista as pv
    pieces = [meshio.read(out_dir / f"{name}_{r}.vtu") for r in range(2)]
    assert all(len(m.points) > 0 and "temperature" in m.point_data for m in pieces)
    par = pv.read(out_dir / f"{name}.pvtu")
    assert par.n_points == sum(len(m.points) for m in pieces)  # the rank boundary's points are in both pieces
    cfg.write_text(cfg.read_text().replace('dir = "out"', 'dir = "serial"'))
    ser = subprocess.run([iga, "run", str(cfg)], capture_output=True, text=True, timeout=600, env=launch_env())
    assert ser.returncode == 0, ser.stderr[-3000:]
    serial = pv.read(tmp_path / "serial" / f"{name}.vtu")
    welded = _welded_like(par, serial, "temperature")
    assert set(serial.point_data.keys()) <= set(welded.point_data.keys())
    # ParaView itself, where it is installed (Debian's paraview 5.11 and xvfb): its parallel reader opens the
    # .pvtu as one dataset, Clean to Grid welds it, and it has the serial file's points, cells and arrays
    import shutil

    if shutil.which("pvpython") and shutil.which("xvfb-run"):
        pv_out = subprocess.run(["xvfb-run", "-a", "pvpython", str(ROOT / "benchmarks" / "paraview_check.py"),
                                 str(out_dir / f"{name}.pvtu"), "--against",
                                 str(tmp_path / "serial" / f"{name}.vtu")],
                                capture_output=True, text=True, timeout=300, env=launch_env())
        assert pv_out.returncode == 0, pv_out.stdout[-2000:] + pv_out.stderr[-2000:]
        assert "same points, cells, point arrays and values" in pv_out.stdout
        bad = subprocess.run(["xvfb-run", "-a", "pvpython", str(ROOT / "benchmarks" / "paraview_check.py"),
                              str(out_dir / "missing.pvtu")], capture_output=True, text=True, timeout=300,
                             env=launch_env())
        assert bad.returncode == 2 and "no such file: " in bad.stderr and "missing.pvtu" in bad.stderr


def test_mpiexec_iga_run_writes_the_elastic_pieces(tmp_path):
    cfg = tmp_path / "beam.toml"
    cfg.write_text(textwrap.dedent("""
        [map]
        primitive = "box"
        args = {size = [0.04, 0.01, 0.01]}
        [tile]
        library = "cross"
        [paving]
        scheme = "regular"
        counts = [4, 1, 1]
        [physics]
        kind = "elasticity"
        youngs = 69e9
        poisson = 0.33
        [[support]]
        tag = "umin"
        [[load]]
        kind = "traction"
        tag = "umax"
        value = [0.0, 0.0, -1e4]
        [solver]
        method = "petsc"
        tol = 1e-12
        [output]
        dir = "out"
        name = "beam"
        png = false
    """))
    iga = str(Path(sys.executable).parent / "iga")
    out = subprocess.run([MPIEXEC, "-n", "2", iga, "run", str(cfg)], capture_output=True, text=True, timeout=600,
                         env=launch_env())
    assert out.returncode == 0, out.stderr[-3000:]
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    elastic = summary["elasticity"]
    assert elastic["solver"]["ranks"] == 2 and elastic["work"]["relative_error"] < 1e-9
    assert summary["files"]["stress_vtu"].endswith("beam_stress.pvtu")
    import meshio
    import pyvista as pv
    pieces = [meshio.read(tmp_path / "out" / f"beam_stress_{r}.vtu") for r in range(2)]
    assert all(len(m.points) > 0 and "displacement" in m.point_data for m in pieces)
    par = pv.read(tmp_path / "out" / "beam_stress.pvtu")
    cfg.write_text(cfg.read_text().replace('dir = "out"', 'dir = "serial"').replace('"petsc"', '"direct"'))
    ser = subprocess.run([iga, "run", str(cfg)], capture_output=True, text=True, timeout=600, env=launch_env())
    assert ser.returncode == 0, ser.stderr[-3000:]
    serial = pv.read(tmp_path / "serial" / "beam_stress.vtu")
    _welded_like(par, serial, "displacement")


def test_more_ranks_than_patches_are_refused(tmp_path):
    out = _mpi(tmp_path, 2, "patch", tmp_path / "x.json")
    assert out.returncode != 0 and "2 MPI ranks for 1 patch" in out.stderr


def test_the_petsc_solver_on_one_process_matches_amg():
    ms = tiling.regular(pr.box((2.0, 1.0, 1.0)), L.cross(), (2, 1, 1))
    a = HeatProblem(ms, degree_elevation=1).dirichlet("umin", 0.0).neumann("umax", 1.0).solve(solver="amg-cg", tol=1e-12)
    p = HeatProblem(ms, degree_elevation=1).dirichlet("umin", 0.0).neumann("umax", 1.0).solve(solver="petsc", tol=1e-12)
    assert np.abs(a.u - p.u).max() < 1e-9 * np.abs(a.u).max()


def test_our_gamg_default_lasts_one_solve_and_the_users_option_wins():
    from solvers.petsc_ksp import _gamg_defaults, petsc

    PETSc = petsc()
    opts = PETSc.Options()
    key = "pc_gamg_aggressive_coarsening" if PETSc.Sys.getVersion() >= (3, 19, 0) else "pc_gamg_square_graph"
    assert _gamg_defaults(PETSc, opts, "gamg") == [key] and opts.getInt(key) == 0
    assert _gamg_defaults(PETSc, opts, "hypre") == []
    opts.delValue(key)
    A = (sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(300, 300)) + 1e-3 * sp.identity(300)).tocsr()
    x, info = solvers.solve(A, np.ones(300), method="petsc", tol=1e-10)
    assert info.iterations > 0 and not opts.hasName(key)  # removed after the solve
    opts[key] = "1"  # as a user's PETSC_OPTIONS would set it
    try:
        assert _gamg_defaults(PETSc, opts, "gamg") == [] and opts.getInt(key) == 1
    finally:
        opts.delValue(key)


def test_a_solves_petsc_options_apply_to_it_and_do_not_outlive_it():
    # PETSc's options database is the process's: a call's petsc_options used to stay set for every later
    # solve; they must still reach the multigrid levels' smoothers, which read them in the set-up
    from solvers.petsc_ksp import petsc

    opts = petsc().Options()
    n = 24
    T = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(n, n))
    I = sp.identity(n)
    A = (sp.kron(sp.kron(T, I), I) + sp.kron(sp.kron(I, T), I) + sp.kron(sp.kron(I, I), T)).tocsr()
    b = np.ones(n ** 3)
    plain, info = solvers.solve(A, b, method="petsc", tol=1e-10)
    smooth, more = solvers.solve(A, b, method="petsc", tol=1e-10,
                                 petsc_options={"mg_levels_ksp_max_it": 8, "pc_gamg_threshold": 0.05})
    assert more.iterations < info.iterations  # the levels' smoothers took the call's option
    assert not opts.hasName("mg_levels_ksp_max_it") and not opts.hasName("pc_gamg_threshold")
    again, after = solvers.solve(A, b, method="petsc", tol=1e-10)
    assert after.iterations == info.iterations and np.abs(again - plain).max() == 0.0
    assert np.abs(smooth - plain).max() < 1e-7 * np.abs(plain).max()
    opts["pc_gamg_threshold"] = "0.01"  # set before the call (as PETSC_OPTIONS would): restored after it
    try:
        solvers.solve(A, b, method="petsc", tol=1e-10, petsc_options={"pc_gamg_threshold": 0.05})
        assert opts.getString("pc_gamg_threshold") == "0.01"
    finally:
        opts.delValue("pc_gamg_threshold")


def test_a_distributed_solve_loads_petsc_with_freed_arrays_returned():
    # Debian's PETSc loads SuperLU_DIST, whose loader turns glibc's unmapping off for the whole process; the
    # distributed path loads PETSc through load_petsc, after which a large array has a mapping of its own
    code = textwrap.dedent("""
        import ctypes, ctypes.util, numpy as np
        class Info(ctypes.Structure):
            _fields_ = [(n, ctypes.c_size_t) for n in
                        "arena ordblks smblks hblks hblkhd usmblks fsmblks uordblks fordblks keepcost".split()]
        libc = ctypes.CDLL(ctypes.util.find_library("c"))
        libc.mallinfo2.restype = Info
        from iga.distributed.solve import load_petsc
        load_petsc()
        info = libc.mallinfo2()
        a = np.ones((info.arena >> 3) + (6 << 20))  # larger than the heap: no free block of it can serve it
        print(libc.mallinfo2().hblkhd - info.hblkhd >= a.nbytes)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300,
                         env=launch_env())
    assert out.returncode == 0, out.stderr
    assert out.stdout.split()[-1] == "True"
