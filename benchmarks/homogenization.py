"""Effective properties of tiles and graded macro models.

    python benchmarks/homogenization.py [--quick]

Table 1: effective conductivity and stiffness of the cross tile (``library.cross(arm)``) against its volume
fraction phi, with the bounds for a porous solid of conductivity k = 1 (E = 1, nu = 0.3): Voigt (phi k),
Hashin-Shtrikman's upper bound for voids, 2 phi k / (3 - phi), and Reuss's (and HS's) lower bound, 0 with
voids (drawn as the axis); the plot
``benchmarks/out/figures/homogenization_bounds.png``.

Table 2: scale separation: the apparent conductivity (heat flow x height / (area x temperature drop)) of
an n x n x n lattice held at two temperatures on opposite faces, against the effective one: the cross
(mirror-symmetric: no boundary layer) and the bent cross (an O(1/n) boundary layer).

Table 3: a graded lattice (``library.graded_cross``: arms 0.2 -> 0.4 along w) in an annulus sector (curved,
rational), held at 1 and 0 on its w faces: heat flow of the full lattice and of its macro model (the map
alone, conductivity from ``iga.effective_table`` through ``iga.macro_map``), their difference and the
speed-up (warm timings; the table's own cell problems are timed apart: a family is tabulated once).
Writes benchmarks/out/homogenization.json.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from _common import figures_dir, print_table, pyplot, save_json


def bounds(quick: bool) -> list[dict]:
    from iga import effective_conductivity, effective_stiffness
    from tiling import library as L

    rows = []
    for arm in (0.2, 0.3, 0.4) if quick else (0.1, 0.2, 0.3, 0.4, 0.5, 0.6):
        eff = effective_conductivity(L.cross(arm), diagnostics=True)
        phi, k = eff.volume_fraction, eff.tensor[0, 0]
        C = effective_stiffness(L.cross(arm), 1.0, 0.3)
        rows.append({"arm": arm, "phi": phi, "k_eff": k, "Voigt": phi, "HS upper": 2 * phi / (3 - phi),
                     "k/HS": k / (2 * phi / (3 - phi)), "C11": C[0, 0], "C12": C[0, 1], "C44": C[3, 3],
                     "E Voigt": phi})
    print("Table 1: the cross tile, k = 1, E = 1, nu = 0.3 (Voigt order; bounds of a porous solid)")
    print_table(rows, [("arm", ".2f"), ("phi", ".4f"), ("k_eff", ".4f"), ("Voigt", ".4f"), ("HS upper", ".4f"),
                       ("k/HS", ".3f"), ("C11", ".4f"), ("C12", ".4f"), ("C44", ".4f")])
    plt = pyplot()
    if plt is not None:
        fig, ax = plt.subplots(figsize=(6, 4))
        phi = np.array([r["phi"] for r in rows])
        ax.plot(phi, [r["k_eff"] for r in rows], "o-", label="cross: k_eff / k")
        ax.plot(phi, [r["C11"] / (1.0 * 0.7 / (1.3 * 0.4)) for r in rows], "s-", label="cross: C11 / C11(solid)")
        ax.plot(phi, phi, "--", label="Voigt")
        ax.plot(phi, 2 * phi / (3 - phi), ":", label="Hashin-Shtrikman upper")
        ax.plot(phi, 0 * phi, "-.", label="Reuss (= HS lower with voids)")
        ax.set_xlabel("volume fraction")
        ax.set_ylabel("effective / solid")
        ax.legend()
        fig.tight_layout()
        fig.savefig(figures_dir() / "homogenization_bounds.png", dpi=120)
        print(f"plot: {figures_dir() / 'homogenization_bounds.png'}")
    return rows


def scale_separation(quick: bool) -> list[dict]:
    from geometry import primitives as pr
    from iga import HeatProblem, effective_conductivity
    from tiling import library as L, regular

    rows = []
    for name, tile, top in (("cross", L.cross(0.3), 16), ("bent cross", L.bent_cross(), 8)):  # (bicubic: 8^3 tiles)
        k_eff = effective_conductivity(tile)[2, 2]
        for n in (2, 4, 8) if quick else tuple(n for n in (2, 4, 8, 16) if n <= top):
            t = time.perf_counter()
            ms = regular(pr.box(), tile, (n, n, n))
            q = HeatProblem(ms, 1.0, degree_elevation=1).dirichlet("wmin", 1.0).dirichlet("wmax", 0.0).solve()
            k = -q.flux("wmin")
            rows.append({"tile": name, "n": n, "tiles": n ** 3, "k apparent": k, "k_eff": k_eff,
                         "relative difference": k / k_eff - 1, "time s": time.perf_counter() - t})
    print("\nTable 2: an n^3 lattice between two plates against the cell problem (same spaces): the mirror-symmetric"
          " cross has no boundary layer, the bent cross (its arms bowed: no mirror symmetry) an O(1/n) one")
    print_table(rows, [("tile", "s"), ("n", "d"), ("tiles", "d"), ("k apparent", ".9f"), ("k_eff", ".9f"),
                       ("relative difference", ".2e"), ("time s", ".1f")])
    return rows


def graded_macro(quick: bool) -> list[dict]:
    from geometry import primitives as pr
    from iga import HeatProblem, effective_table, macro_map
    from tiling import graded, library as L
    from tiling.materials import graded_channel

    t = time.perf_counter()
    table = effective_table(L.cross, np.linspace(0.15, 0.45, 7))
    t_table = time.perf_counter() - t
    D = graded_channel(pr.annulus(1.0, 1.3, 0.6, angle=0.4), "arm", 0.2, 0.4, "wmin")

    def macro():
        Dm, names = macro_map(D, table, "arm")
        return HeatProblem(Dm, conductivity=names, degree_elevation=1).dirichlet("wmin", 1.0).dirichlet(
            "wmax", 0.0).solve().flux("wmin")

    macro()  # warm: imports and compiled kernels are not the work measured
    t = time.perf_counter()
    q_macro = macro()
    t_macro = time.perf_counter() - t
    rows = []
    for n in (1, 2) if quick else (1, 2, 4, 8):
        counts = (3 * n, 2 * n, 4 * n)
        t = time.perf_counter()
        ms = graded(D, L.graded_cross, counts, "arm")
        q = HeatProblem(ms, 1.0, degree_elevation=1).dirichlet("wmin", 1.0).dirichlet("wmax", 0.0).solve().flux("wmin")
        t_full = time.perf_counter() - t
        rows.append({"cells": "x".join(map(str, counts)), "patches": len(ms.patches), "full W": q, "macro W": q_macro,
                     "difference": q_macro / q - 1, "full s": t_full, "macro s": t_macro,
                     "speed-up": t_full / t_macro, "table s": t_table})
    print("\nTable 3: graded lattice (arms 0.2 -> 0.4 along w) in an annulus sector, and its macro model "
          "(target: within 2%, 50x faster)")
    print_table(rows, [("cells", "s"), ("patches", "d"), ("full W", ".6f"), ("macro W", ".6f"), ("difference", ".1e"),
                       ("full s", ".2f"), ("macro s", ".3f"), ("speed-up", ".0f"), ("table s", ".2f")])
    return rows


def main() -> None:
    quick = "--quick" in sys.argv
    out = {"bounds": bounds(quick), "scale separation": scale_separation(quick), "graded macro": graded_macro(quick)}
    save_json("homogenization.json", out)
    print("wrote benchmarks/out/homogenization.json")


if __name__ == "__main__":
    main()
