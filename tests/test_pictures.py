"""Results at hand: a solution as a pyvista grid equal to the solution, and a titled picture of it."""

import numpy as np
import pytest

from geometry import primitives as pr
from iga import ElasticityProblem, HeatProblem, ProblemError


def _heat():
    return HeatProblem(pr.box((2.0, 1.0, 1.0), degrees=(2, 2, 2)), conductivity=3.0).dirichlet(
        "umin", 40.66).dirichlet("umax", 40.88).solve()


def test_a_solution_as_a_pyvista_grid_holds_the_solution_at_its_points():
    s = _heat()
    grid = s.to_pyvista(samples=2)
    x = np.asarray(grid.points)
    rng = np.random.default_rng(0)
    pick = rng.choice(len(x), 20, replace=False)
    assert np.allclose(grid.point_data["temperature"][pick], s.probe(x[pick]), atol=1e-10)
    # T linear in x: the flux -k dT/dx = -3 * 0.22 / 2 everywhere
    assert np.allclose(grid.point_data["heat_flux"], [-0.33, 0.0, 0.0], atol=1e-9)


def test_pictures_are_titled_and_state_a_narrow_range(tmp_path):
    import pyvista as pv

    s = _heat()
    png = s.plot(screenshot=tmp_path / "t.png")
    img = pv.read(png)
    assert img.dimensions[:2] == (1200, 850) and np.ptp(np.asarray(img.point_data[img.array_names[0]])) > 0
    e = ElasticityProblem(pr.box(degrees=(2, 2, 2)), 200e9, 0.3).dirichlet("umin", 0.0).traction(
        "umax", (0.0, 0.0, 1e6)).solve()
    assert e.plot(screenshot=tmp_path / "e.png", warp=100.0).stat().st_size > 10_000
    with pytest.raises(ProblemError, match=r"plot: no field 'pressure'; this result has "
                                           r"\['conductivity', 'heat_flux', 'temperature'\]"):
        s.plot("pressure", screenshot=tmp_path / "x.png")
    with pytest.raises(ProblemError, match=r"warp needs a displacement field"):
        from iga.io.pictures import plot_field

        plot_field(s.to_pyvista(), "temperature", "t", tmp_path / "w.png", warp=2.0)
    assert not (tmp_path / "x.png").exists() and not (tmp_path / "w.png").exists()


def test_the_title_says_how_narrow_the_range_is():
    from iga.io import pictures

    texts = []

    class Plotter:  # records what the picture would say, without rendering
        def add_mesh(self, *a, **k):
            texts.append(k["scalar_bar_args"]["title"])

        def add_text(self, text, **k):
            texts.append(text)

    grid = _heat().to_pyvista()
    orig = pictures.offscreen_plotter
    pictures.offscreen_plotter = lambda window: Plotter()
    orig_save = pictures.save_screenshot
    pictures.save_screenshot = lambda pl, path, *a: path
    try:
        pictures.plot_field(grid, "temperature", "a sink", "p.png")
    finally:
        pictures.offscreen_plotter, pictures.save_screenshot = orig, orig_save
    assert texts[0] == "temperature (C)"
    assert texts[1].startswith("a sink\ntemperature 40.66 .. 40.88 C (a range of 0.22 C)")


def test_a_microstructure_draws_itself_titled(tmp_path):
    import pyvista as pv
    import tiling
    from tiling import TilingError
    from tiling import library as L

    ms = tiling.regular(pr.box(degrees=(2, 2, 2)), L.cross(), (2, 1, 1))
    png = ms.plot(screenshot=tmp_path / "ms.png", samples=2)
    assert pv.read(png).dimensions[:2] == (1000, 800)
    with pytest.raises(TilingError, match=r"color_by must be one of \['level', 'patch', 'tile'\], got 'colour'"):
        ms.plot(screenshot=tmp_path / "x.png", color_by="colour")
    assert not (tmp_path / "x.png").exists()


def test_a_microstructure_draws_the_boundary_it_was_given_and_refuses_another_s(tmp_path, monkeypatch):
    import pyvista as pv
    import tiling
    from tiling import TilingError, pictures
    from tiling import library as L

    ms = tiling.regular(pr.box(degrees=(2, 2, 2)), L.cross(), (2, 1, 1))
    boundary = ms.surface(samples=2)
    again = ms.surface(samples=2)
    other = tiling.regular(pr.box(degrees=(2, 2, 2)), L.cross(), (3, 2, 1)).surface(samples=2)
    drawn = []
    monkeypatch.setattr(pictures, "surface", lambda *a, **k: drawn.append(a) or again)
    png = ms.plot(screenshot=tmp_path / "ms.png", mesh=boundary, color_by="tile")
    assert drawn == [] and pv.read(png).dimensions[:2] == (1000, 800)  # drawn as given, not computed again
    for bad in (other, pv.Sphere(), "boundary.stl"):
        with pytest.raises(TilingError, match="mesh must be the boundary surface"):
            ms.plot(screenshot=tmp_path / "x.png", mesh=bad)
    assert not (tmp_path / "x.png").exists()
    monkeypatch.undo()
    assert ms.plot(screenshot=tmp_path / "y.png", samples=2).stat().st_size > 0  # without mesh=: computed
