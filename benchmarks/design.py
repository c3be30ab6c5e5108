"""Design by gradient: the aluminium/steel grading of the vertical heat sink optimised for its hottest point.

The sink of ``iga demo heat-sink --variant vertical`` (Massarwi et al. 2018, Fig. 11: 2 x 2 base tiles of pins,
two levels) cooled hard, 2 W/cm^2 into its base and h = 3000 W/(m^2 K) to a coolant at 0 C on every other face
(temperatures are rises), so that conduction inside the part carries most of the temperature rise (the split of
the uniform design is printed).  The conductivity is a channel k of the deformation map, k = 54 + 151 phi W/(m K)
for an aluminium volume fraction phi; the uniform design has phi = 1/2 everywhere (k = 129.5).  The design
variables are the 216 control values of k on the map with its knot spans bisected twice (the same geometry and
tiling), bounded by steel (54) and aluminium (205); the constraint keeps the volume mean of k, i.e. the volume
of each metal and so the aluminium mass and the solid volume.  The objective is TemperatureNorm(16), a smooth
maximum; SLSQP (`iga.optimize`).  Verified by fresh analyses of both designs at one refinement more: the largest
sampled temperature rise of each.

Also measured: the cost of one gradient (the adjoint by the forward solve's kept factorisation, and one pass over
the Gauss points) against one forward analysis (as the optimiser runs it, keeping its factorisation) on the
vertical and circular demo sinks and a 10^3 lattice of crosses, and against finite differences (one analysis per
variable).

Targets: the verified maximum rise at least 10% lower than the uniform design's; gradient / forward <= 1.5.
Then the same sink designed by its shape instead (uniform k): the map's control points moved at the same solid
volume, the heated face held (`iga.optimize(..., wrt="map")`), verified the same way.
Then a lattice graded in three directions by its tiles' own parameters: 4 x 4 x 1 face-graded crosses
(`tiling.field_graded`, `library.face_graded_cross`) whose arm widths on every cell wall come from a parameter
spline of 27 control values (`wrt="parameters"`), heated through its bottom (held: the same heated area and
power) and cooled hard on its top, at the uniform design's solid volume; verified at one refinement more, and
the cost of its gradient against its forward analysis.
Then a cantilever lattice of 8 x 2 x 2 face-graded crosses (80 x 20 x 20 mm, aluminium) clamped at one end and
loaded by a traction on the other (held: the same area, so the same force), its arm widths graded for least
compliance at the uniform design's solid volume (`wrt="parameters"` of an elastic solution: the compliance is
self-adjoint), verified at one refinement more.
Then the sink's pins and metals together (``--part pins``): the vertical map paved by one level of T2 whose pins
take their widths from a parameter spline on the cell walls (`library.face_graded_heat_sink`, `tiling.field_graded`;
32 control values, widths in [0.1, 0.49]), the same cooling; first the pins at the uniform k and the solid volume
of T2's pins (0.45), then the aluminium/steel grading (216 control values of k) at that geometry and the uniform
mean of k; verified at one refinement more against the uniform design (T2's pins, k = 129.5), with each step's
share of the gain.
Then the cantilever designed on its homogenised macro model (``--part macro``): a finer lattice, 16 x 4 x 4
face-graded crosses (80 x 20 x 20 mm, aluminium, quadratic), whose arm widths come from a parameter field of 54
control values (degree 2, 4 x 1 x 1 spans); the macro model is the beam alone with the cross's cubic effective
stiffness tabulated over the arm width (`iga.stiffness_table`, `iga.CubicMaterial`: C11, C12, C44 as cubic
splines of the width), the same field as its channel; SLSQP on the macro model at the uniform design's solid
fraction (`iga.optimize(..., keep_fraction=True)`, the gradient exact for the macro model), then both lattices
analysed in full: the uniform one at the graded one's exact solid volume, the same 4 N on the loaded end; both
compliances of both models printed, and the gaps.
Not measured here: the base's thickness (the side walls of
neighbouring cells share their control points, so a per-cell base height cannot conform; one height for the whole
sink is a move of the map's control points, the shape design above), and hierarchical pavings with a parameter
field.

    python benchmarks/design.py                  # writes benchmarks/out/design.json and the pictures
    python benchmarks/design.py --part lattice   # only the graded lattice (also: costs, channel, shape,
                                                 # pins, cantilever, macro)
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from _common import figures_dir, print_table, save_json, settle


def vertical(D=None, k=129.5):
    import tiling
    from iga.app.maps import vertical_heat_sink_map
    from tiling import library

    D = vertical_heat_sink_map() if D is None else D
    D = D.with_channel("k", np.full(D.control_points.shape[:3], k))
    return tiling.hierarchical(D, library.heat_sink_t2(), counts=(2, 2), levels=2, scale=0.5), D


def conditions(problem):
    return problem.neumann("branch-in", 2e4).robin("exterior", 3000.0, 0.0)


def timed(fn):
    settle()
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def gradient_costs(repeats: int = 5):
    """Forward analysis against one gradient, on three models whose conductivity is a channel of the map: the
    median of ``repeats`` runs, each on a fresh problem (single timings of these 0.1 s analyses moved by 50%)."""
    import iga
    import tiling
    from geometry import primitives as pr
    from iga.app.maps import circular_heat_sink_map
    from iga.outputs import TemperatureNorm
    from iga.sensitivity import channel_sensitivity
    from iga.shape_sensitivity import shape_sensitivity
    from tiling import library
    from tiling.materials import graded_channel

    cases = {"vertical sink": conditions(iga.HeatProblem(vertical()[0], conductivity="k"))}
    D = graded_channel(circular_heat_sink_map(), "k", near=205.0, far=54.0, face="wmin")
    circ = tiling.hierarchical(D, library.heat_sink_t1(), counts=(4, 1), levels=3, scale=0.5)
    cases["circular sink"] = iga.HeatProblem(circ, conductivity="k").neumann("branch-in", 1515.8).robin(
        "exterior", 5.0, 30.0)
    B = pr.box((0.03, 0.03, 0.03), degrees=(2, 2, 2))
    B = B.with_channel("k", np.full(B.control_points.shape[:3], 205.0))
    lattice = tiling.regular(B, library.cross(0.4), (10, 10, 10))
    cases["10^3 crosses"] = iga.HeatProblem(lattice, conductivity="k").neumann("umin", 5000.0).robin(
        "rest", 10.0, 20.0)
    rows = []
    for name, problem in cases.items():
        problem.solve(keep=True)  # compiled kernels and cached tables in place: what a design loop's later steps see
        times = []
        for _ in range(repeats):  # a fresh problem and solution each time, as every design step has
            fresh = problem.on(problem.model)
            # the forward analysis as the optimiser runs it: keeping its factorisation for the adjoint
            s, forward = timed(lambda fresh=fresh: fresh.solve(keep=True))
            g, grad = timed(lambda s=s: channel_sensitivity(s, TemperatureNorm(8), "k"))
            fresh = problem.on(problem.model)
            s, forward_shape = timed(lambda fresh=fresh: fresh.solve(keep=True))
            gs, shape = timed(lambda s=s: shape_sensitivity(s, TemperatureNorm(8)))
            times.append((forward, grad, forward_shape, shape))
        forward, grad, forward_shape, shape = np.median(times, axis=0)
        rows.append({"model": name, "unknowns": int(s.info.free_dofs), "variables": g.size, "forward_s": forward,
                     "gradient_s": grad, "ratio": grad / forward, "fd_ratio": g.size * forward / grad,
                     "shape_variables": gs.size, "shape_s": shape, "shape_ratio": shape / forward_shape})
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--maxiter", type=int, default=40)
    ap.add_argument("--figures", action="store_true", help="write the pictures to docs/ (make_figures.py)")
    ap.add_argument("--part", default="all",
                    choices=("all", "costs", "channel", "shape", "pins", "lattice", "cantilever", "macro"),
                    help="run one part only (its figures printed; design.json is written by 'all')")
    args = ap.parse_args(argv)
    if args.part != "all":
        {"costs": lambda: print_table(gradient_costs(), _COST_COLUMNS), "channel": lambda: channel_design(args),
         "shape": lambda: shape_design(args.maxiter), "pins": lambda: pins_design(args.maxiter),
         "lattice": lambda: lattice_design(args.maxiter),
         "cantilever": lambda: cantilever_design(args.maxiter), "macro": lambda: macro_design(args.maxiter)
         }[args.part]()
        return
    costs = gradient_costs()
    print("gradient against forward analysis (TemperatureNorm(8): d/dk of every control value of the map's k, and "
          "d/dP of every control point coordinate of the map, wrt='map'):")
    print_table(costs, _COST_COLUMNS)
    print("(ratio, shape_ratio: gradient / forward, target <= 1.5; fd_ratio: finite differences / gradient)\n")
    channel = channel_design(args)
    shape = shape_design(args.maxiter)
    pins = pins_design(args.maxiter)
    lattice = lattice_design(args.maxiter)
    cantilever = cantilever_design(args.maxiter)
    macro = macro_design(args.maxiter)
    save_json("design.json", {"gradient_costs": costs, **channel, "shape": shape, "pins": pins, "lattice": lattice,
                              "cantilever": cantilever, "macro": macro})


_COST_COLUMNS = [("model", ">14"), ("unknowns", ",d"), ("variables", "d"), ("forward_s", ".3f"), ("gradient_s", ".3f"),
                 ("ratio", ".2f"), ("fd_ratio", ".0f"), ("shape_variables", "d"), ("shape_s", ".3f"),
                 ("shape_ratio", ".2f")]


def channel_design(args) -> dict:
    """The vertical sink's aluminium/steel grading (module notes), verified at one refinement more."""
    import iga
    from iga.design import channel_volumes, redesigned
    from iga.io.pictures import render_temperature
    from iga.io.vtu import sampled_grid
    from iga.outputs import MeanTemperature, TemperatureNorm

    sink, D = vertical()
    Dr = D.refine(2)[0]  # the same geometry, 6 x 6 x 6 control values of k
    sink = redesigned(sink, D, Dr, True)
    problem = conditions(iga.HeatProblem(sink, conductivity="k"))
    uniform = problem.solve()
    tmax = uniform.temperature_range(4)[1]
    surface = MeanTemperature("exterior").value(uniform)
    print(f"uniform design (k = 129.5 W/(m K)): largest rise {tmax:.4f} K = conduction {tmax - surface:.4f} K "
          f"({100 * (tmax - surface) / tmax:.0f}%) + convection {surface:.4f} K (mean surface rise)")
    result, seconds = timed(lambda: iga.optimize(problem, TemperatureNorm(16), "channel:k", (54.0, 205.0),
                                                 mean=129.5, maxiter=args.maxiter))
    print(f"SLSQP: {len(result.history)} iterations, {result.evaluations} analyses with their gradients, "
          f"{seconds:.1f} s; {result.message}")
    print(f"TemperatureNorm(16): {result.initial:.4f} -> {result.objective:.4f} K "
          f"({100 * result.improvement:.1f}% lower)")

    # verification: fresh analyses at one refinement more
    def verify(values):
        model = redesigned(sink, Dr, Dr.with_channel("k", values), True)
        s = conditions(iga.HeatProblem(model, conductivity="k", refine=1)).solve()
        return s, s.temperature_range(4)[1]

    su, tu = verify(np.full(Dr.control_points.shape[:3], 129.5))
    so, to = verify(result.values)
    vol = channel_volumes(problem, Dr, True)
    fraction = (vol @ result.values.reshape(-1) / vol.sum() - 54.0) / 151.0
    print(f"verified at refine 1 ({su.info.free_dofs:,} unknowns): largest rise uniform {tu:.4f} K, optimised "
          f"{to:.4f} K: {100 * (tu - to) / tu:.1f}% lower (target >= 10%)")
    print(f"solid volume {su.volume() * 1e6:.4f} cm^3 (both designs); aluminium volume fraction: uniform 0.500, "
          f"optimised {fraction:.4f}; control values {result.values.min():.0f} .. {result.values.max():.0f} W/(m K)")
    folder = figures_dir()
    for name, s in (("design_uniform", su), ("design_optimised", so)):
        render_temperature(sampled_grid(s.problem.model, s, 3), folder / f"{name}.png", title="rise (K)",
                           caption=f"vertical sink, {name.split('_')[1]}: largest rise "
                                   f"{s.temperature_range(4)[1]:.3f} K")
        print(f"picture: {folder / (name + '.png')}")
    return {"uniform_rise_K": tu, "optimised_rise_K": to, "objective": [result.initial, result.objective],
            "iterations": len(result.history), "analyses": result.evaluations, "seconds": seconds,
            "values": result.values.tolist()}


def shape_design(maxiter: int) -> dict:
    """The same sink (uniform k = 129.5) designed by its shape: the map's control points moved by at most an eighth
    of their spacing, the base's bottom (the map's wmin, where the heat enters) held so that the heated area and
    the power stay, the solid volume kept; TemperatureNorm(16); verified at one refinement more."""
    import iga
    from iga.design import redesigned
    from iga.outputs import TemperatureNorm, Volume
    from iga.shape_design import moved_map

    sink, D = vertical()
    problem = conditions(iga.HeatProblem(sink, conductivity="k"))
    P = np.array(D.control_points)[..., :3]
    spacing = min(float(np.abs(np.diff(P, axis=k)).max(axis=-1).min()) for k in range(3))
    move = spacing / 8
    result, seconds = timed(lambda: iga.optimize(problem, TemperatureNorm(16), "map", bounds=move, hold=("wmin",),
                                                 maxiter=maxiter))
    print(f"\nshape design ({int(np.prod(P.shape))} coordinates, the wmin face held, moves up to {move * 1e3:.2f} "
          f"mm, solid volume kept): {len(result.history)} iterations, {result.evaluations} analyses, {seconds:.1f} s;"
          f" {result.message}")
    print(f"TemperatureNorm(16): {result.initial:.4f} -> {result.objective:.4f} K "
          f"({100 * result.improvement:.1f}% lower)")
    rows = []
    for name, model in (("uniform", sink), ("shape", redesigned(sink, D, moved_map(D, result.values), True))):
        s = conditions(iga.HeatProblem(model, conductivity="k", refine=1)).solve()
        b = s.balance()
        rows.append({"design": name, "unknowns": int(s.info.free_dofs), "largest_rise_K": s.temperature_range(4)[1],
                     "volume_cm3": Volume().value(s) * 1e6, "power_W": b.inflow_W})
    print_table(rows, [("design", ">8"), ("unknowns", ",d"), ("largest_rise_K", ".4f"), ("volume_cm3", ".5f"),
                       ("power_W", ".4f")])
    lower = 100 * (rows[0]["largest_rise_K"] - rows[1]["largest_rise_K"]) / rows[0]["largest_rise_K"]
    print(f"verified at refine 1: the largest rise {lower:.1f}% lower at the same volume and power")
    return {"objective": [result.initial, result.objective], "iterations": len(result.history),
            "analyses": result.evaluations, "seconds": seconds, "move_m": move, "verified": rows,
            "largest_rise_lower_percent": lower}


def _pinned_sink(widths, k=None, **kw):
    """The vertical sink of one level of pins whose widths come from the parameter spline of control values
    ``widths`` (4, 4, 2) (degree 2 along u and v, 1 along w; the side walls sit at mid-height, so both w values
    count alike), its map's k the control values ``k`` (6, 6, 6) on the map with its spans bisected twice (None:
    129.5 everywhere on the map itself, which keeps the paving's parameter field for wrt="parameters"), cooled as
    :func:`conditions` says (the map's wmin is the base's bottom)."""
    import iga
    import tiling
    from geometry import SplineFunction
    from geometry import knots as kn
    from iga.design import redesigned
    from tiling import library

    _, D = vertical()
    U = kn.uniform_knots(2, 2)
    field = SplineFunction((2, 2, 1), [U, U, kn.uniform_knots(1, 1)], np.asarray(widths, float).reshape(4, 4, 2, 1))
    ms = tiling.field_graded(D, library.face_graded_heat_sink, (4, 4, 1), field)
    if k is not None:  # the same geometry, k on 216 control values (the paving stays; the grading is not carried)
        ms = redesigned(ms, D, D.refine(2)[0].with_channel("k", k), True)
    return iga.HeatProblem(ms, conductivity="k", **kw).neumann("wmin", 2e4).robin("boundary - wmin", 3000.0, 0.0)


def pins_design(maxiter: int) -> dict:
    """The sink's pins, then its metals (module notes); verified at one refinement more."""
    import iga
    from iga.io.pictures import render_temperature
    from iga.io.vtu import sampled_grid
    from iga.outputs import TemperatureNorm, Volume

    uniform = np.full((4, 4, 2), 0.45)
    pins, t_pins = timed(lambda: iga.optimize(_pinned_sink(uniform), TemperatureNorm(16), wrt="parameters",
                                              bounds=(0.1, 0.49), maxiter=maxiter))
    start = np.full((6, 6, 6), 129.5)
    metals, t_metals = timed(lambda: iga.optimize(_pinned_sink(pins.values, start), TemperatureNorm(16), "channel:k",
                                                  (54.0, 205.0), mean=129.5, maxiter=max(maxiter, 40)))
    print(f"\npins and metals of a one-level vertical sink: the pins ({pins.values.size} control values of the "
          f"widths) {len(pins.history)} SLSQP iterations, {t_pins:.1f} s, TemperatureNorm(16) {pins.initial:.4f} -> "
          f"{pins.objective:.4f} K; then k ({metals.values.size} control values) {len(metals.history)} iterations, "
          f"{t_metals:.1f} s, -> {metals.objective:.4f} K at the volume mean of k {metals.history[-1].mean:.2f} "
          f"W/(m K) (129.5: the same aluminium volume)")
    rows = []
    folder = figures_dir()
    for name, widths, k in (("uniform", uniform, None), ("pins", pins.values, None),
                            ("pins + metals", pins.values, metals.values)):
        s = _pinned_sink(widths, k, refine=1).solve()
        rows.append({"design": name, "unknowns": int(s.info.free_dofs), "largest_rise_K": s.temperature_range(4)[1],
                     "volume_cm3": Volume().value(s) * 1e6, "power_W": s.balance().inflow_W})
        if name != "pins":
            png = folder / f"pins_{name.split()[0].replace('pins', 'graded')}.png"
            caption = f"one-level vertical sink, {name}: largest rise {rows[-1]['largest_rise_K']:.3f} K"
            render_temperature(sampled_grid(s.problem.model, s, 3), png, title="rise (K)", caption=caption)
    print_table(rows, [("design", ">14"), ("unknowns", ",d"), ("largest_rise_K", ".4f"), ("volume_cm3", ".5f"),
                       ("power_W", ".4f")])
    base = rows[0]["largest_rise_K"]
    lower = [100 * (base - r["largest_rise_K"]) / base for r in rows[1:]]
    print(f"verified at refine 1: the largest rise {lower[0]:.1f}% lower by the pins alone, {lower[1]:.1f}% with "
          f"the metals too (target >= 10%), at the same solid volume and power; widths "
          f"{pins.values.min():.3f} .. {pins.values.max():.3f}")
    return {"pins": {"objective": [pins.initial, pins.objective], "iterations": len(pins.history),
                     "seconds": t_pins, "values": pins.values.tolist()},
            "metals": {"objective": [metals.initial, metals.objective], "iterations": len(metals.history),
                       "seconds": t_metals},
            "verified": rows, "largest_rise_lower_percent": lower}


def _lattice(widths):
    """The graded lattice of the module notes with the parameter spline of control values ``widths`` (3, 3, 3)."""
    import iga
    import tiling
    from geometry import SplineFunction
    from geometry import knots as kn
    from geometry import primitives as pr
    from tiling import library

    U = kn.uniform_knots(2, 1)
    D = pr.box((0.04, 0.04, 0.01), degrees=(1, 1, 1))
    field = SplineFunction((2, 2, 2), [U, U, U], np.asarray(widths, float).reshape(3, 3, 3, 1))
    ms = tiling.field_graded(D, library.face_graded_cross, (4, 4, 1), field)
    return lambda **kw: iga.HeatProblem(ms, conductivity=205.0, **kw).neumann("wmin", 2e4).robin("wmax", 3000.0,
                                                                                                  0.0)


def lattice_design(maxiter: int) -> dict:
    """The graded lattice (module notes): arm widths in [0.15, 0.6] from 0.35 everywhere, the bottom held, the
    solid volume kept; TemperatureNorm(8); verified at one refinement more; its gradient's cost."""
    import iga
    from iga.io.pictures import render_temperature
    from iga.io.vtu import sampled_grid
    from iga.outputs import TemperatureNorm, Volume

    problem = _lattice(np.full((3, 3, 3), 0.35))()
    problem.solve(keep=True)  # kernels and tables in place
    s, forward = timed(lambda: problem.solve(keep=True))
    g, grad = timed(lambda: s.gradient(TemperatureNorm(8), wrt="parameters"))
    print(f"\ngraded lattice: {s.info.free_dofs:,} unknowns, {g.size} variables: forward {forward:.3f} s, gradient "
          f"{grad:.3f} s (ratio {grad / forward:.2f}; finite differences / gradient {g.size * forward / grad:.0f})")
    result, seconds = timed(lambda: iga.optimize(problem, TemperatureNorm(8), wrt="parameters", bounds=(0.15, 0.6),
                                                 hold=("wmin",), maxiter=maxiter))
    print(f"SLSQP: {len(result.history)} iterations, {result.evaluations} analyses, {seconds:.1f} s; "
          f"{result.message}")
    print(f"TemperatureNorm(8): {result.initial:.4f} -> {result.objective:.4f} K "
          f"({100 * result.improvement:.1f}% lower)")
    rows = []
    folder = figures_dir()
    for name, widths in (("uniform", np.full((3, 3, 3), 0.35)), ("graded", result.values)):
        v = _lattice(widths)(refine=1).solve()
        b = v.balance()
        rows.append({"design": name, "unknowns": int(v.info.free_dofs), "largest_rise_K": v.temperature_range(4)[1],
                     "volume_cm3": Volume().value(v) * 1e6, "power_W": b.inflow_W})
        render_temperature(sampled_grid(v.problem.model, v, 3), folder / f"lattice_{name}.png", title="rise (K)",
                           caption=f"graded lattice, {name}: largest rise {rows[-1]['largest_rise_K']:.3f} K")
    print_table(rows, [("design", ">8"), ("unknowns", ",d"), ("largest_rise_K", ".4f"), ("volume_cm3", ".5f"),
                       ("power_W", ".4f")])
    lower = 100 * (rows[0]["largest_rise_K"] - rows[1]["largest_rise_K"]) / rows[0]["largest_rise_K"]
    print(f"verified at refine 1: the largest rise {lower:.1f}% lower at the same volume and power; pictures "
          f"{folder / 'lattice_uniform.png'}, {folder / 'lattice_graded.png'}")
    print("control values (k = 0: the held bottom; k = 2: the cooled top):\n" + np.array2string(
        result.values.round(3)))
    return {"unknowns": int(s.info.free_dofs), "variables": int(g.size), "forward_s": forward, "gradient_s": grad,
            "objective": [result.initial, result.objective], "iterations": len(result.history),
            "analyses": result.evaluations, "seconds": seconds, "verified": rows, "largest_rise_lower_percent": lower,
            "values": result.values.tolist()}


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
    picture = _render_pair(grids, [f"{r['design']}: lattice compliance {r['lattice_J'] * 1e6:.2f} uJ, macro model "
                                   f"{r['macro_J'] * 1e6:.2f} uJ" for r in rows], figures_dir() / "macro_cantilever.png")
    print(f"verified on the full lattice: the compliance {lower:.1f}% lower at the same solid volume and force "
          f"(uniform width {w_match:.4f} matched to the graded lattice's volume); picture {picture}")
    print("field control values (x along the rows; middle of y; z across):\n"
          + np.array2string(result.values[:, 1, :].round(3)))
    return {"table_s": t_table, "objective": [result.initial, result.objective], "iterations": len(result.history),
            "analyses": result.evaluations, "seconds": seconds, "verified": rows, "compliance_lower_percent": lower,
            "uniform_width": w_match, "values": result.values.tolist()}


if __name__ == "__main__":
    main()
