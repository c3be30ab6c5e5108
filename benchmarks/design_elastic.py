"""Design by gradient, elastic parts of ``benchmarks/design.py`` (run them there: ``--part cantilever``,
``--part macro``; the module notes of ``design.py`` say what each measures): a cantilever lattice graded on the
full lattice, and one designed on its homogenised macro model and verified on the full lattice."""

from __future__ import annotations

import numpy as np

from _common import figures_dir, print_table, timed


def _cantilever(widths, **kw):
    """The cantilever lattice of the module notes with the parameter spline of control values ``widths``."""
    import tiling
    from geometry import SplineFunction
    from geometry import knots as kn
    from geometry import primitives as pr
    from iga import ElasticityProblem
    from tiling import library

    U = kn.uniform_knots(2, 1)
    D = pr.box((0.08, 0.02, 0.02), degrees=(1, 1, 1))
    field = SplineFunction((2, 2, 2), [U, U, U], np.asarray(widths, float).reshape(3, 3, 3, 1))
    ms = tiling.field_graded(D, library.face_graded_cross, (8, 2, 2), field)
    return ElasticityProblem(ms, youngs=7e10, poisson=0.33, **kw).dirichlet("umin", 0.0).traction(
        "umax", [0.0, 0.0, -1e5])


def cantilever_design(maxiter: int) -> dict:
    """The cantilever lattice (module notes): arm widths in [0.15, 0.6] from 0.35, the loaded end held, the
    solid volume kept; Compliance(); verified at one refinement more."""
    import iga
    from iga.outputs import Compliance, Volume

    uniform = np.full((3, 3, 3), 0.35)
    result, seconds = timed(lambda: iga.optimize(_cantilever(uniform), Compliance(), wrt="parameters",
                                                 bounds=(0.15, 0.6), hold=("umax",), maxiter=maxiter))
    print(f"\ncantilever lattice: SLSQP {len(result.history)} iterations, {result.evaluations} analyses, "
          f"{seconds:.1f} s; {result.message}")
    print(f"compliance: {result.initial:.6g} -> {result.objective:.6g} J ({100 * result.improvement:.1f}% lower)")
    rows = []
    for name, widths in (("uniform", uniform), ("graded", result.values)):
        s = _cantilever(widths, refine=1).solve()
        rows.append({"design": name, "unknowns": int(s.info.free_dofs), "compliance_J": Compliance().value(s),
                     "volume_cm3": Volume().value(s) * 1e6, "support_force_z_N": float(s.reaction("umin")[2])})
    print_table(rows, [("design", ">8"), ("unknowns", ",d"), ("compliance_J", ".6g"), ("volume_cm3", ".5f"),
                       ("support_force_z_N", ".4f")])
    lower = 100 * (rows[0]["compliance_J"] - rows[1]["compliance_J"]) / rows[0]["compliance_J"]
    print(f"verified at refine 1: the compliance {lower:.1f}% lower at the same volume and load")
    return {"objective": [result.initial, result.objective], "iterations": len(result.history),
            "analyses": result.evaluations, "seconds": seconds, "verified": rows, "compliance_lower_percent": lower,
            "values": result.values.tolist()}


#: the macro part's beam (m), cells, force on the loaded end (N), aluminium (Pa, -), field spans and width bounds
_BEAM, _CELLS, _FORCE, _ALU, _SPANS, _WIDTHS = (0.08, 0.02, 0.02), (16, 4, 4), 4.0, (7e10, 0.33), (4, 1, 1), (0.15, 0.6)


def _field(values):
    """The arm-width field: a quadratic spline of control values (6, 3, 3) on the beam's normalised parameters."""
    from geometry import SplineFunction
    from geometry import knots as kn

    U = [kn.uniform_knots(2, n) for n in _SPANS]
    return SplineFunction((2, 2, 2), U, np.asarray(values, float).reshape(6, 3, 3, 1))


def _macro_problem(values, table):
    """The macro model: the beam (its map of the field's degree and spans) with the cross's cubic stiffness at its
    channel t, clamped at x = 0, the force spread over the end x = L; cubic elements, 16 x 4 x 4 of them."""
    from geometry import primitives as pr
    from iga import ElasticityProblem

    D = pr.box(_BEAM, degrees=(2, 2, 2)).refine(2, [0])[0]
    area = _BEAM[1] * _BEAM[2]
    return (ElasticityProblem(D.with_channel("t", np.asarray(values, float)), material=table.material("t"),
                              degree_elevation=1, refine=2)
            .dirichlet("umin", 0.0).traction("umax", [0.0, 0.0, -_FORCE / area]))


def _lattice_problem(values):
    """The full lattice graded by the field, quadratic (the cell problems' spaces), clamped at its arm ends at
    x = 0 and loaded on its arm ends at x = L by the same force (the traction over their area)."""
    import tiling
    from geometry import primitives as pr
    from iga import ElasticityProblem
    from tiling import library

    ms = tiling.field_graded(pr.box(_BEAM, degrees=(1, 1, 1)), library.face_graded_cross, _CELLS, _field(values))
    ends = ms.info["faces"][0][-1]  # the arm widths on the cells' walls at x = L (cell fractions)
    area = float(np.sum(ends**2)) * (_BEAM[1] / _CELLS[1]) * (_BEAM[2] / _CELLS[2])
    return ElasticityProblem(ms, youngs=_ALU[0], poisson=_ALU[1], degree_elevation=1).dirichlet("umin", 0.0) \
        .traction("umax", [0.0, 0.0, -_FORCE / area])


def _uniform_at(volume: float) -> float:
    """The uniform arm width whose lattice has the solid ``volume`` (m^3): a root of the lattice's exact volume."""
    from scipy.optimize import brentq

    return float(brentq(lambda w: _lattice_volume(np.full((6, 3, 3), w)) - volume, _WIDTHS[0], _WIDTHS[1],
                        xtol=1e-10))


def _lattice_volume(values) -> float:
    """The lattice's solid volume (m^3): its patches' |det J| summed by the problem's Gauss rule (no solve)."""
    from iga.outputs import gauss_pass

    problem, total = _lattice_problem(values), [0.0]

    def add(chunk, space, vals, grads, wv, x, chans):
        total[0] += float(wv.sum())

    gauss_pass(problem, np.zeros((1, problem.ndof)), add)
    return total[0]


def _render_pair(grids, captions, path):
    """The uniform lattice above the graded one, seen from the side (y), coloured by the von Mises stress on one
    scale; the clamped end on the left."""
    from geometry.io.files import offscreen_plotter, save_screenshot

    hi = max(float(np.percentile(g.point_data["von_mises"], 99.5)) for g in grids)
    pl = offscreen_plotter((1400, 800))
    for k, (grid, caption) in enumerate(zip(grids, captions)):
        shifted = grid.translate((0.0, 0.0, -0.035 * k), inplace=False)
        pl.add_mesh(shifted, scalars="von_mises", cmap="viridis", clim=(0.0, hi),
                    scalar_bar_args={"title": "von Mises (Pa)", "vertical": True, "position_x": 0.86, "fmt": "%.2g"})
        pl.add_text(caption, position=(20, 760 - 380 * k), font_size=11, color="black")
    pl.add_text("clamped at the left, 4 N down on the right end; colour scale clipped at the 99.5th percentile",
                position="lower_left", font_size=9, color="black")
    return save_screenshot(pl, path, camera="xz", zoom=1.2)


def macro_design(maxiter: int) -> dict:
    """The cantilever designed on its macro model and verified on the full lattice (module notes)."""
    import iga
    from iga.outputs import Compliance, Volume
    from tiling import library

    def member(w):
        return library.face_graded_cross(w, w, w, w, w, w)

    table, t_table = timed(lambda: iga.stiffness_table(member, np.linspace(*_WIDTHS, 10), *_ALU, name="cross"))
    w0 = 0.35
    uniform = np.full((6, 3, 3), w0)
    macro0 = _macro_problem(uniform, table)
    result, seconds = timed(lambda: iga.optimize(macro0, Compliance(), wrt="channel:t", bounds=_WIDTHS,
                                                 keep_fraction=True, maxiter=maxiter))
    fraction = float(table.fraction([w0])[0])
    print(f"\nmacro cantilever: the cross's cubic stiffness at 10 widths in {t_table:.1f} s (cubic to "
          f"{table.cubic_error:.1e}); macro model {result.solution.info.free_dofs:,} unknowns, "
          f"{result.values.size} variables")
    print(f"SLSQP on the macro model: {len(result.history)} iterations, {result.evaluations} analyses, {seconds:.1f} "
          f"s; {result.message}; solid fraction {fraction:.4f} -> {result.history[-1].mean:.4f}")
    print(f"macro compliance: {result.initial:.6g} -> {result.objective:.6g} J "
          f"({100 * result.improvement:.1f}% lower)")
    graded = _lattice_problem(result.values).solve()
    volume = Volume().value(graded)
    w_match = _uniform_at(volume)
    rows, grids = [], []
    for name, values, lattice in (("uniform", np.full((6, 3, 3), w_match), None), ("graded", result.values, graded)):
        lattice = _lattice_problem(values).solve() if lattice is None else lattice
        macro = Compliance().value(_macro_problem(values, table).solve())
        full = Compliance().value(lattice)
        rows.append({"design": name, "lattice_unknowns": int(lattice.info.free_dofs), "macro_J": macro,
                     "lattice_J": full, "gap_percent": 100 * (macro - full) / full,
                     "volume_cm3": Volume().value(lattice) * 1e6, "force_z_N": float(lattice.reaction("umin")[2])})
        grids.append(lattice.to_pyvista(3))
    print_table(rows, [("design", ">8"), ("lattice_unknowns", ",d"), ("macro_J", ".5g"), ("lattice_J", ".5g"),
                       ("gap_percent", "+.1f"), ("volume_cm3", ".4f"), ("force_z_N", ".4f")])
    lower = 100 * (rows[0]["lattice_J"] - rows[1]["lattice_J"]) / rows[0]["lattice_J"]
    captions = [f"{r['design']}: lattice compliance {r['lattice_J'] * 1e6:.2f} uJ, macro model "
                f"{r['macro_J'] * 1e6:.2f} uJ" for r in rows]
    picture = _render_pair(grids, captions, figures_dir() / "macro_cantilever.png")
    print(f"verified on the full lattice: the compliance {lower:.1f}% lower at the same solid volume and force "
          f"(uniform width {w_match:.4f} matched to the graded lattice's volume); picture {picture}")
    print("field control values (x along the rows; middle of y; z across):\n"
          + np.array2string(result.values[:, 1, :].round(3)))
    return {"table_s": t_table, "objective": [result.initial, result.objective], "iterations": len(result.history),
            "analyses": result.evaluations, "seconds": seconds, "verified": rows, "compliance_lower_percent": lower,
            "uniform_width": w_match, "values": result.values.tolist()}
