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
Then the sink's pins, base and metals (``--part pins``): the vertical map (its u and v spans bisected) paved by
one level of T2 whose pins take their widths from a parameter spline on the cell walls
(`library.face_graded_heat_sink`, `tiling.field_graded`; 32 control values, widths in [0.1, 0.49]), the same
cooling; first the pins at the uniform k and the solid volume of T2's pins (0.45), then the base's thickness (the
heights of the map's 16 middle control points between its held bottom and top, `wrt="map", axes="z"`, the solid
volume kept), then the aluminium/steel grading (216 control values of k) at that geometry and the uniform mean of
k; verified at one refinement more against the uniform design (T2's pins, k = 129.5), with each step's share of
the gain.  The same for the demo's two-level sink (``--part sink``): its 16 leaves graded (`tiling.leaf_graded`),
its base, its metals.
Then the cantilever designed on its homogenised macro model (``--part macro``): a finer lattice, 16 x 4 x 4
face-graded crosses (80 x 20 x 20 mm, aluminium, quadratic), whose arm widths come from a parameter field of 54
control values (degree 2, 4 x 1 x 1 spans); the macro model is the beam alone with the cross's cubic effective
stiffness tabulated over the arm width (`iga.stiffness_table`, `iga.CubicMaterial`: C11, C12, C44 as cubic
splines of the width), the same field as its channel; SLSQP on the macro model at the uniform design's solid
fraction (`iga.optimize(..., keep_fraction=True)`, the gradient exact for the macro model), then both lattices
analysed in full: the uniform one at the graded one's exact solid volume, the same 4 N on the loaded end; both
compliances of both models printed, and the gaps.
Not measured here: a parameter field on the inner levels of a hierarchical paving (their pins carry the next
level's branch faces).

    python benchmarks/design.py                  # writes benchmarks/out/design.json and the pictures
    python benchmarks/design.py --part lattice   # only the graded lattice (also: costs, channel, shape,
                                                 # pins, sink, cantilever, macro)
"""

from __future__ import annotations

import argparse

import numpy as np

from _common import figures_dir, print_table, save_json, timed
from design_elastic import cantilever_design, macro_design


def vertical(D=None, k=129.5):
    import tiling
    from iga.app.maps import vertical_heat_sink_map
    from tiling import library

    D = vertical_heat_sink_map() if D is None else D
    D = D.with_channel("k", np.full(D.control_points.shape[:3], k))
    return tiling.hierarchical(D, library.heat_sink_t2(), counts=(2, 2), levels=2, scale=0.5), D


def conditions(problem):
    return problem.neumann("branch-in", 2e4).robin("exterior", 3000.0, 0.0)


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
                    choices=("all", "costs", "channel", "shape", "pins", "sink", "lattice", "cantilever", "macro"),
                    help="run one part only (its figures printed; design.json is written by 'all')")
    args = ap.parse_args(argv)
    if args.part != "all":
        {"costs": lambda: print_table(gradient_costs(), _COST_COLUMNS), "channel": lambda: channel_design(args),
         "shape": lambda: shape_design(args.maxiter), "pins": lambda: pins_design(args.maxiter),
         "sink": lambda: sink_design(args.maxiter),
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
    sink = sink_design(args.maxiter)
    lattice = lattice_design(args.maxiter)
    cantilever = cantilever_design(args.maxiter)
    macro = macro_design(args.maxiter)
    save_json("design.json", {"gradient_costs": costs, **channel, "shape": shape, "pins": pins, "sink": sink,
                              "lattice": lattice, "cantilever": cantilever, "macro": macro})


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


def _sink_map():
    """The vertical demo map (k = 129.5) with its u and v spans bisected: 4 x 4 control points in plan, whose middle
    layer's heights set where the tiles' base ends (the base's thickness across the sink, moved by ``axes="z"``)."""
    _, D = vertical()
    return D.refine(1, [0, 1])[0]


def _pinned_sink(widths, k=None, D=None, **kw):
    """The vertical sink of one level of pins whose widths come from the parameter spline of control values
    ``widths`` (4, 4, 2) (degree 2 along u and v, 1 along w; the side walls sit at mid-height, so both w values
    count alike), on the map ``D`` (default :func:`_sink_map`; a design of its heights moves the base's top), its
    k the control values ``k`` (6, 6, 6) on that map with 4 spans in every direction (None: 129.5 everywhere on the
    map itself, which keeps the paving's parameter field for wrt="parameters"), cooled as :func:`conditions`
    says (the map's wmin is the base's bottom)."""
    import iga
    import tiling
    from geometry import SplineFunction
    from geometry import knots as kn
    from iga.design import redesigned
    from tiling import library

    D = _sink_map() if D is None else D
    U = kn.uniform_knots(2, 2)
    field = SplineFunction((2, 2, 1), [U, U, kn.uniform_knots(1, 1)], np.asarray(widths, float).reshape(4, 4, 2, 1))
    ms = tiling.field_graded(D, library.face_graded_heat_sink, (2, 2, 1), field)  # 4 x 4 cells
    if k is not None:  # the same geometry, k on 216 control values (the paving stays; the grading is not carried)
        ms = redesigned(ms, D, D.refine(1, [0, 1])[0].refine(2, [2])[0].with_channel("k", k), True)
    return iga.HeatProblem(ms, conductivity="k", **kw).neumann("wmin", 2e4).robin("boundary - wmin", 3000.0, 0.0)


def _base_thickness(D) -> np.ndarray:
    """The base's thickness (mm) at the 4 x 4 cell centres: where the tiles' solid base ends (w = 0.4 of T2's
    height) above the heated face, through the map."""
    c = (np.arange(4) + 0.5) / 4
    u, v = np.meshgrid(c, c, indexing="ij")
    at = lambda w: D.evaluate(np.column_stack([u.ravel(), v.ravel(), np.full(16, w)]))[:, 2]  # noqa: E731
    return ((at(0.4) - at(0.0)) * 1e3).reshape(4, 4)


def pins_design(maxiter: int) -> dict:
    """The sink's pins, then its base, then its metals (module notes); verified at one refinement more."""
    import iga
    from iga.io.pictures import render_temperature
    from iga.io.vtu import sampled_grid
    from iga.outputs import TemperatureNorm, Volume
    from iga.shape_design import moved_map

    uniform = np.full((4, 4, 2), 0.45)
    pins, t_pins = timed(lambda: iga.optimize(_pinned_sink(uniform), TemperatureNorm(16), wrt="parameters",
                                              bounds=(0.1, 0.49), maxiter=maxiter))
    base, t_base = timed(lambda: iga.optimize(_pinned_sink(pins.values), TemperatureNorm(16), wrt="map",
                                              bounds=0.006, hold=("wmin", "wmax"), axes="z", maxiter=maxiter))
    D = moved_map(_sink_map(), base.values)
    start = np.full((6, 6, 6), 129.5)
    metals, t_metals = timed(lambda: iga.optimize(_pinned_sink(pins.values, start, D), TemperatureNorm(16),
                                                  "channel:k", (54.0, 205.0), mean=129.5, maxiter=max(maxiter, 40)))
    thick = _base_thickness(D)
    print(f"\npins, base and metals of a one-level vertical sink: the pins ({pins.values.size} control values of the "
          f"widths) {len(pins.history)} SLSQP iterations, {t_pins:.1f} s, TemperatureNorm(16) {pins.initial:.4f} -> "
          f"{pins.objective:.4f} K; then the base (the heights of 16 control points of the map between its held "
          f"bottom and top) {len(base.history)} iterations, {t_base:.1f} s, -> {base.objective:.4f} K, its thickness "
          f"{thick.min():.2f} .. {thick.max():.2f} mm (12 uniform); then k ({metals.values.size} control values) "
          f"{len(metals.history)} iterations, {t_metals:.1f} s, -> {metals.objective:.4f} K at the volume mean of k "
          f"{metals.history[-1].mean:.2f} W/(m K) (129.5: the same aluminium volume)")
    rows = []
    folder = figures_dir()
    for name, widths, k, Dm in (("uniform", uniform, None, None), ("pins", pins.values, None, None),
                                ("pins + base", pins.values, None, D), ("pins + base + metals", pins.values,
                                                                         metals.values, D)):
        s = _pinned_sink(widths, k, Dm, refine=1).solve()
        rows.append({"design": name, "unknowns": int(s.info.free_dofs), "largest_rise_K": s.temperature_range(4)[1],
                     "volume_cm3": Volume().value(s) * 1e6, "power_W": s.balance().inflow_W})
        if name in ("uniform", "pins + base + metals"):
            png = folder / f"pins_{'uniform' if name == 'uniform' else 'graded'}.png"
            caption = f"one-level vertical sink, {name}: largest rise {rows[-1]['largest_rise_K']:.3f} K"
            render_temperature(sampled_grid(s.problem.model, s, 3), png, title="rise (K)", caption=caption)
    print_table(rows, [("design", ">20"), ("unknowns", ",d"), ("largest_rise_K", ".4f"), ("volume_cm3", ".5f"),
                       ("power_W", ".4f")])
    first = rows[0]["largest_rise_K"]
    lower = [100 * (first - r["largest_rise_K"]) / first for r in rows[1:]]
    print(f"verified at refine 1: the largest rise {lower[0]:.1f}% lower by the pins alone, {lower[1]:.1f}% with "
          f"the base, {lower[2]:.1f}% with the metals too (target >= 10%), at the same solid volume and power; "
          f"widths {pins.values.min():.3f} .. {pins.values.max():.3f}; base thickness (mm) at the cell centres:\n"
          + np.array2string(thick.round(2)))
    return {"pins": {"objective": [pins.initial, pins.objective], "iterations": len(pins.history),
                     "seconds": t_pins, "values": pins.values.tolist()},
            "base": {"objective": [base.initial, base.objective], "iterations": len(base.history),
                     "seconds": t_base, "thickness_mm": thick.tolist()},
            "metals": {"objective": [metals.initial, metals.objective], "iterations": len(metals.history),
                       "seconds": t_metals},
            "verified": rows, "largest_rise_lower_percent": lower}


def _two_level(widths, k=None, D=None, **kw):
    """The demo's two-level vertical sink (T2, 2 x 2 base tiles) whose 16 leaves are face_graded_heat_sink members
    with the widths of the parameter spline of control values ``widths`` (4, 4, 2) (:func:`tiling.leaf_graded`), on
    the map ``D`` (default :func:`_sink_map`, one base tile per knot span), k as :func:`_pinned_sink` takes it."""
    import iga
    import tiling
    from geometry import SplineFunction
    from geometry import knots as kn
    from iga.design import redesigned
    from tiling import library

    D = _sink_map() if D is None else D
    U = kn.uniform_knots(2, 2)
    field = SplineFunction((2, 2, 1), [U, U, kn.uniform_knots(1, 1)], np.asarray(widths, float).reshape(4, 4, 2, 1))
    ms = tiling.leaf_graded(D, library.heat_sink_t2(), (1, 1), 2, library.face_graded_heat_sink, field, scale=0.5)
    if k is not None:
        ms = redesigned(ms, D, D.refine(1, [0, 1])[0].refine(2, [2])[0].with_channel("k", k), True)
    return conditions(iga.HeatProblem(ms, conductivity="k", **kw))


def _level0_base(problem, D) -> np.ndarray:
    """The base thickness (mm) of the four base tiles at their centres: T2's solid base ends at 0.4 of its height."""
    out = []
    for p in problem.model.patches:
        if p.level == 0:
            y = np.array([[0.5, 0.5, 0.4], [0.5, 0.5, 0.0]]) @ p.placement[:, :3].T + p.placement[:, 3]
            z = D.evaluate(y)[:, 2]
            out.append((z[0] - z[1]) * 1e3)
    return np.array(out)


def sink_design(maxiter: int) -> dict:
    """The two-level vertical sink of the demo: its leaves' pins, its base, its metals (module notes); verified
    at one refinement more."""
    import iga
    from iga.io.pictures import render_temperature
    from iga.io.vtu import sampled_grid
    from iga.outputs import MeanTemperature, TemperatureNorm, Volume
    from iga.shape_design import moved_map

    uniform = np.full((4, 4, 2), 0.45)
    first = _two_level(uniform).solve()
    tmax, surface = first.temperature_range(4)[1], MeanTemperature("exterior").value(first)
    print(f"\ntwo-level vertical sink, uniform (T2, k = 129.5): largest rise {tmax:.4f} K = conduction "
          f"{tmax - surface:.4f} K ({100 * (tmax - surface) / tmax:.0f}%) + convection {surface:.4f} K")
    pins, t_pins = timed(lambda: iga.optimize(_two_level(uniform), TemperatureNorm(16), wrt="parameters",
                                              bounds=(0.1, 0.49), maxiter=maxiter))
    base, t_base = timed(lambda: iga.optimize(_two_level(pins.values), TemperatureNorm(16), wrt="map",
                                              bounds=0.006, hold=("wmin", "wmax"), axes="z", maxiter=maxiter))
    D = moved_map(_sink_map(), base.values)
    metals, t_metals = timed(lambda: iga.optimize(_two_level(pins.values, np.full((6, 6, 6), 129.5), D),
                                                  TemperatureNorm(16), "channel:k", (54.0, 205.0), mean=129.5,
                                                  maxiter=max(maxiter, 40)))
    print(f"the leaves' pins ({pins.values.size} control values) {len(pins.history)} SLSQP iterations, "
          f"{t_pins:.1f} s, TemperatureNorm(16) {pins.initial:.4f} -> {pins.objective:.4f} K; the base (16 heights "
          f"of the map) {len(base.history)} iterations, {t_base:.1f} s, -> {base.objective:.4f} K; k (216 control "
          f"values) {len(metals.history)} iterations, {t_metals:.1f} s, -> {metals.objective:.4f} K at the mean k "
          f"{metals.history[-1].mean:.2f} W/(m K)")
    rows = []
    for name, widths, k, Dm in (("uniform", uniform, None, None), ("pins", pins.values, None, None),
                                ("pins + base", pins.values, None, D),
                                ("pins + base + metals", pins.values, metals.values, D)):
        s = _two_level(widths, k, Dm, refine=1).solve()
        rows.append({"design": name, "unknowns": int(s.info.free_dofs), "largest_rise_K": s.temperature_range(4)[1],
                     "volume_cm3": Volume().value(s) * 1e6, "power_W": s.balance().inflow_W})
        if name in ("uniform", "pins + base + metals"):
            png = figures_dir() / f"sink_{'uniform' if name == 'uniform' else 'graded'}.png"
            render_temperature(sampled_grid(s.problem.model, s, 3), png, title="rise (K)",
                               caption=f"two-level vertical sink, {name}: largest rise "
                                       f"{rows[-1]['largest_rise_K']:.3f} K")
    print_table(rows, [("design", ">20"), ("unknowns", ",d"), ("largest_rise_K", ".4f"), ("volume_cm3", ".5f"),
                       ("power_W", ".4f")])
    top = rows[0]["largest_rise_K"]
    lower = [100 * (top - r["largest_rise_K"]) / top for r in rows[1:]]
    thick = _level0_base(first.problem, D)
    print(f"verified at refine 1: the largest rise {lower[0]:.1f}% lower by the leaves' pins, {lower[1]:.1f}% with "
          f"the base, {lower[2]:.1f}% with the metals too (target >= 10%), at the same solid volume and power; "
          f"widths {pins.values.min():.3f} .. {pins.values.max():.3f}; base thickness at the base tiles' centres "
          f"{thick.min():.2f} .. {thick.max():.2f} mm ({_level0_base(first.problem, _sink_map())[0]:.2f} uniform)")
    return {"conduction_share": (tmax - surface) / tmax, "verified": rows, "largest_rise_lower_percent": lower,
            "iterations": [len(pins.history), len(base.history), len(metals.history)],
            "seconds": [t_pins, t_base, t_metals], "base_mm": thick.tolist()}


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


if __name__ == "__main__":
    main()
