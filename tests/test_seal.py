"""Sealed pavings: trivariate cap and shell plates conforming to the tiles, in the heat model."""

import numpy as np
import pytest

import tiling
from geometry import MultiPatch, primitives as pr
from iga import HeatProblem
from tiling import TilingError
from tiling import library as L
from tiling.sealing.plates import sealed_variant

from helpers import surface_area

AFFINE = pr.box((2.0, 1.0, 1.5))


def linear(x):
    return 1 + 2 * x[:, 0] - x[:, 1] + 0.5 * x[:, 2]


def test_a_variant_glues_every_sealed_tile_face_to_one_plate():
    tile = L.cross()
    v = sealed_variant(tile, {"umin", "wmax"}, 0.1)
    n = len(tile.patches)
    assert v.seal_patches == tuple(range(n, len(v.patches)))
    model = MultiPatch.from_splines(v.patches)  # refuses touching faces that do not conform
    glued = {(i.a, i.b) for i in model.interfaces} | {(i.b, i.a) for i in model.interfaces}
    # the arm ends on umin and wmax (tile patches 1 and 6) each meet exactly one plate
    for p, f in ((1, "umin"), (6, "wmax")):
        partners = [b for a, b in glued if a == (p, f)]
        assert len(partners) == 1 and partners[0][0] >= n
    # the tile is squeezed out of the sealed layers, nothing else moves
    pts = np.concatenate([p.control_points[..., :3].reshape(-1, 3) for p in v.patches[:n]])
    assert pts[:, 0].min() == pytest.approx(0.1) and pts[:, 2].max() == pytest.approx(0.9)
    assert pts[:, 1].min() == pytest.approx(0.0) and pts[:, 1].max() == pytest.approx(1.0)
    # plates fill the sealed layers exactly: tile volume + plate volume = the cell minus the lattice's voids
    vol = sum(np.prod(np.ptp(p.control_points[..., :3].reshape(-1, 3), axis=0)) for p in v.patches[n:])
    layer = 1 - 0.9 * 0.9  # two layers of 0.1 meeting along an edge
    assert vol == pytest.approx(layer, rel=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize("seal,sides,refine", [("cap", ("wmax", "umin"), 1), ("shell", None, 0)])
def test_patch_test_with_seal_plates(seal, sides, refine):
    ms = tiling.regular(AFFINE, L.cross(), (3, 2, 2) if refine else (2, 1, 2), seal=seal, seal_sides=sides)
    s = HeatProblem(ms, degree_elevation=1, refine=refine).dirichlet("boundary", linear).solve()
    assert s.l2_error(linear) < 1e-9
    assert s.info["constraints"]["identity_pairs"] > 0 and len(ms.tags[seal]) > 0
    # variants are built once per set of sealed sides, not per placed copy
    assert len({id(t) for t in ms.tiles}) <= 3 * 2 * 2 + 1


def test_heat_through_the_cap_balances_and_matches_the_cap_area():
    ms = tiling.regular(AFFINE, L.cross(), (3, 2, 2), seal="cap", seal_sides=("wmax",))
    top = ms.tags["wmax"]
    assert top and all(f in set(ms.tags["cap"]) for f in top)  # the top is all cap now
    s = HeatProblem(ms, conductivity=50.0).neumann("wmax", 800.0).dirichlet("wmin", 20.0).solve()
    assert s.info["balance"]["relative_error"] < 1e-9
    assert s.info["components"]["count"] == 1 and not s.info["components"]["idle"]  # one coupled piece: no interface missing
    # independent: the cap covers the whole top of D, whose area is that of D's face
    area = surface_area(AFFINE.boundary("wmax"))
    assert sum(surface_area(ms.patches[i].composed.boundary(f)) for i, f in top) == pytest.approx(area, rel=1e-12)
    assert s.flux("wmax") == pytest.approx(-800.0 * area, rel=1e-10)
    assert s.flux("wmin") == pytest.approx(800.0 * area, rel=1e-8)


@pytest.mark.slow
def test_a_shelled_lattice_is_closed_with_its_inner_void():
    twisted = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.3, axis_point=(0.5, 0.5))
    ms = tiling.regular(twisted, L.cross(), (2, 2, 2), seal="shell", thickness=0.15)
    w = tiling.export.watertightness(ms)
    # the outside of the shell and the void around the lattice inside it: two closed sheets
    assert w["closed"] and w["manifold"] and w["components"] == 2
    s = HeatProblem(ms, conductivity=20.0).neumann("umin", 100.0).robin("umax", 10.0, 20.0).solve()
    assert s.info["balance"]["relative_error"] < 1e-8
    assert s.info["components"]["count"] == 1 and not s.info["components"]["idle"]  # one coupled piece: no interface missing


def test_one_cell_is_sealed_on_both_sides():
    ms = tiling.regular(AFFINE, L.cross(), (1, 1, 1), seal="shell")
    (t,) = ms.tiles
    assert t.name.endswith("(shell umax+umin+vmax+vmin+wmax+wmin)")
    # grid lines 0, t, the arms' edges, 1 - t, 1 on every axis: 5^3 boxes, the tile's 3^3 inside
    assert len(t.seal_patches) == 5 ** 3 - 3 ** 3


SINK = pr.box((0.06, 0.06, 0.03))


@pytest.mark.slow
def test_a_hierarchy_capped_on_top_and_bottom_passes_the_patch_test_and_is_closed():
    # the lid meets 16 fin tops and the slots between them: refinement interfaces where a plate meets part of a
    # fin's face, identity where it meets a whole one
    ms = tiling.hierarchical(SINK, L.heat_sink_t2(), (2, 2), levels=2, seal="cap", seal_sides=("wmin", "wmax"))
    plates = {id(t): t for t in ms.tiles if t.name.startswith("heat_sink_t2 cap")}
    assert len(plates) == 1  # one layout for every base cell (all are sealed on the same sides), not one per cell
    plate_ids = {id(p) for t in plates.values() for p in t.patches}
    to_plate = [i for i in ms.interfaces if i.kind == "branch" and id(ms.patches[i.b[0]].spline) in plate_ids]
    assert len(to_plate) > 0
    s = HeatProblem(ms).dirichlet("boundary", linear).solve()
    assert s.l2_error(linear) < 1e-9
    assert ms.tags["branch-in"] == [] and ms.tags["branch-out"] == []  # base and fin tips are covered now
    w = tiling.export.watertightness(ms)
    assert w["closed"] and w["manifold"] and w["components"] == 1


def test_heat_through_the_lid_of_a_capped_heat_sink():
    ms = tiling.hierarchical(SINK, L.heat_sink_t2(), (2, 2), levels=2, seal="cap", seal_sides=("wmax",))
    lid = ms.tags["wmax"]
    assert lid and set(lid) <= set(ms.tags["cap"])
    s = HeatProblem(ms, conductivity=200.0).neumann("wmax", -5e4).dirichlet("branch-in", 60.0).solve()
    assert s.info["balance"]["relative_error"] < 1e-9
    assert s.info["components"]["count"] == 1 and not s.info["components"]["idle"]  # one coupled piece: no interface missing
    area = surface_area(SINK.boundary("wmax"))  # the lid covers D's whole top face
    assert s.flux("wmax") == pytest.approx(5e4 * area, rel=1e-10)
    assert s.flux("branch-in") == pytest.approx(-5e4 * area, rel=1e-8)


def test_a_tapered_side_cannot_be_capped_by_box_plates():
    with pytest.raises(TilingError, match="heat_sink_t2.*umin.*leave umin out of seal_sides"):
        tiling.hierarchical(SINK, L.heat_sink_t2(), (2, 2), levels=2, seal="cap")
    inside = tiling.Tile([pr.box((0.5, 0.5, 0.5), (0.25, 0.25, 0.25))], name="floating block")
    with pytest.raises(TilingError, match="floating block.*no boundary faces on the cell walls"):
        tiling.regular(AFFINE, inside, (2, 2, 2), seal="cap")


def test_seal_bad_input():
    with pytest.raises(TilingError, match="seal must be"):
        tiling.regular(AFFINE, L.cross(), (2, 2, 2), seal="lid")
    with pytest.raises(TilingError, match="not both"):
        tiling.regular(AFFINE, L.cross(), (2, 2, 2), seal="cap", variants={(0, 0, 1): L.cross()})
    with pytest.raises(TilingError, match="thickness"):
        tiling.regular(AFFINE, L.cross(), (2, 2, 2), seal="cap", thickness=0.6)
    with pytest.raises(TilingError, match="shell.*thickness"):
        tiling.regular(AFFINE, L.cross(), (2, 2, 2), seal="shell", thickness=0.5)  # thicker than half a cell
    with pytest.raises(TilingError, match="no trivariate patches"):
        sealed_variant(L.hollow_box(), {"umin"})
    # a surface tile whose walls lie on the cell faces is closed there already: capping adds nothing
    assert tiling.regular(AFFINE, L.hollow_box(), (2, 2, 2), seal="cap").caps == []
    with pytest.raises(TilingError, match="seal_sides"):
        tiling.regular(AFFINE, L.cross(), (2, 2, 2), seal="cap", seal_sides=("top",))


def _sealed_config(**paving):
    return {"map": {"primitive": "box", "args": {"size": [2.0, 1.0, 1.0]}}, "tile": {"library": "cross"},
            "paving": {"scheme": "regular", "counts": [4, 2, 2], **paving},
            "material": {"conductivity": 50.0},
            "bc": [{"kind": "neumann", "tag": "cap", "value": 500.0}, {"kind": "dirichlet", "tag": "wmin", "value": 20.0}],
            "output": {"png": False, "vtu": False}}


def test_pipeline_with_a_sealed_paving(tmp_path):
    from iga.app.pipeline import run_pipeline

    summary = run_pipeline(_sealed_config(seal="cap", seal_sides=["wmax"], thickness=0.15), tmp_path)
    assert summary["energy_balance_error"] < 1e-9 and summary["temperature_C"]["max"] > 20.0
    assert summary["connected_pieces"] == 1  # the paving is one coupled piece
    assert summary["inflow_W"] == pytest.approx(summary["outflow_W"], rel=1e-9)


def test_pipeline_with_a_capped_hierarchy(tmp_path):
    from iga.app.pipeline import run_pipeline

    cfg = _sealed_config()
    cfg["map"]["args"]["size"] = [0.06, 0.06, 0.03]
    cfg["tile"] = {"library": "heat_sink_t1"}
    cfg["paving"] = {"scheme": "hierarchical", "counts": [2, 2], "levels": 2, "seal": "cap", "seal_sides": ["wmax"]}
    cfg["bc"] = [{"kind": "neumann", "tag": "branch-in", "value": 1e4}, {"kind": "robin", "tag": "cap", "h": 50.0, "ambient": 20.0}]
    summary = run_pipeline(cfg, tmp_path)
    assert summary["energy_balance_error"] < 1e-9 and summary["temperature_C"]["min"] > 20.0
    assert summary["connected_pieces"] == 1  # the paving is one coupled piece


@pytest.mark.parametrize("paving,match", [
    (dict(seal="lid"), "paving.seal"), (dict(thickness=0.1), "needs paving.seal"),
    (dict(seal="cap", seal_sides=["top"]), "paving.seal_sides"), (dict(seal="cap", thickness=0.7), "paving.thickness")])
def test_pipeline_seal_errors_name_the_key(tmp_path, paving, match):
    from iga import ProblemError
    from iga.app.pipeline import run_pipeline

    with pytest.raises(ProblemError, match=match):
        run_pipeline(_sealed_config(**paving), tmp_path)


@pytest.mark.slow
def test_surface_to_a_tolerance():
    D = pr.twisted(pr.box((1.0, 1.0, 1.0), degrees=(2, 2, 2)), 0.5, axis_point=(0.5, 0.5))
    ms = tiling.regular(D, L.cross(), (2, 2, 2))
    s = [tiling.export.samples_for_tolerance(ms, tol) for tol in (1e-2, 1e-4, 1e-5)]
    assert s == sorted(s) and s[-1] > s[0]
    coarse, fine = ms.surface(tolerance=1e-2), ms.surface(tolerance=1e-5)
    assert fine.n_cells > coarse.n_cells
    assert tiling.export.mesh_watertightness(fine)["closed"] == tiling.export.mesh_watertightness(coarse)["closed"]
    with pytest.raises(TilingError, match="raise the tolerance"):
        tiling.export.samples_for_tolerance(ms, 1e-14, max_samples=4)
    with pytest.raises(TilingError, match="tolerance"):
        ms.surface(tolerance=-1.0)


def test_seal_plates_are_not_counted_as_tiles():
    plain = tiling.hierarchical(SINK, L.heat_sink_t2(), (2, 2), levels=2)
    lid = tiling.hierarchical(SINK, L.heat_sink_t2(), (2, 2), levels=2, seal="cap", seal_sides=("wmax",))
    assert lid.tiles_per_level() == plain.tiles_per_level() == [4, 16] and lid.n_tiles == plain.n_tiles
    assert len(lid.patches) > len(plain.patches)  # the plates are there, as patches
