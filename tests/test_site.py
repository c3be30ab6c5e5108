"""The documentation site and its gallery: every script under examples/ runs and draws the picture the gallery
shows, the gallery page lists every script, and the site builds with warnings as errors."""

import subprocess
import sys
from pathlib import Path

import pytest
from commands import run_script

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("*.py"))


def test_the_gallery_lists_every_example_with_its_picture():
    page = (ROOT / "docs" / "gallery.md").read_text()
    assert len(EXAMPLES) >= 5 and sum(s.stem.startswith("paper_") for s in EXAMPLES) >= 8
    for script in EXAMPLES:
        assert f"](gallery/{script.stem}.png)" in page and f"`examples/{script.name}`" in page
        assert (ROOT / "docs" / "gallery" / f"{script.stem}.png").stat().st_size > 20_000
        code = script.read_text()
        assert code.startswith('"""')  # the docstring states the case the gallery shows
        assert "title=" in code or ".plot(" not in code  # and the picture states it too


@pytest.mark.slow
@pytest.mark.parametrize("script", EXAMPLES, ids=[s.stem for s in EXAMPLES])
def test_every_example_runs_and_draws_its_picture(script, tmp_path):
    run = run_script(script, tmp_path, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    assert (tmp_path / f"{script.stem}.png").stat().st_size > 20_000
    assert run.stdout.strip()  # it says what it computed


@pytest.mark.slow
def test_the_site_builds_without_warnings(tmp_path):
    pytest.importorskip("mkdocs")
    pytest.importorskip("mkdocstrings")
    run = subprocess.run([sys.executable, str(ROOT / "docs" / "build_site.py"), "--no-examples", "--site-dir",
                          str(tmp_path / "site")], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, (run.stdout + run.stderr)[-3000:]
    for page in ("index.html", "gallery/index.html", "api/index.html", "transient/index.html"):
        assert (tmp_path / "site" / page).stat().st_size > 1000
    api = (tmp_path / "site" / "api" / "index.html").read_text()
    assert "TransientHeatProblem" in api and "capacity" in api  # the reference holds the docstrings


def test_the_site_navigation_and_landing_page_list_every_page_the_readme_lists():
    import re

    readme = (ROOT / "README.md").read_text()
    pages = set(re.findall(r"\]\(docs/([\w-]+\.md)\)", readme))
    index = set(re.findall(r"\]\(([\w-]+\.md)\)", (ROOT / "docs" / "index.md").read_text()))
    nav = set(re.findall(r":\s*([\w-]+\.md)\s*$", (ROOT / "mkdocs.yml").read_text(), re.M))
    on_disk = {p.name for p in (ROOT / "docs").glob("*.md")}
    assert pages <= index, f"pages in the README but not on the site's landing page: {sorted(pages - index)}"
    assert on_disk <= nav, f"pages left out of the site's navigation: {sorted(on_disk - nav)}"


def test_the_tiles_page_shows_every_tile_of_the_library_with_its_picture():
    import sys

    from tiling.library import TILES

    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from tile_gallery import page
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    text = (ROOT / "docs" / "tiles.md").read_text()
    assert text == page(), "docs/tiles.md is stale: python benchmarks/tile_gallery.py --figures"
    for name in TILES:
        assert f"](tiles/{name}.png)" in text and (ROOT / "docs" / "tiles" / f"{name}.png").stat().st_size > 5_000
