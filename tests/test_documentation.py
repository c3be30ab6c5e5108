"""The README as a guide: short, the two commands first, its script runs as written, every link leads to a file,
and it speaks of the software, not of how it was made."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
from commands import iga_command, run_code

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()
COMMANDS = ['python -m pip install -e . && iga demo heat-sink --out heat-sink-out',
            'python -m pip install -e ".[test]" && python -m pytest -q -n auto --dist worksteal -m "slow or not slow"']
# words of a development log: issue numbers, dated runs, numbered sessions or rounds of changes
NARRATION = re.compile(r"issue #\d|\b20\d\d-\d\d-\d\d\b|\bsession\b|\b(sixth|seventh|eighth|ninth|tenth|eleventh|"
                       r"twelfth) (session|round)|rounds? of changes", re.I)


def test_the_readme_is_short_and_starts_with_the_two_commands():
    lines = README.splitlines()
    assert len(lines) <= 200, f"README.md has {len(lines)} lines"
    first = re.search(r"```bash\n(.*?)```", README, re.S)
    assert first is not None and first.start() < README.index("\n## ")
    assert first.group(1).strip().splitlines() == COMMANDS
    ci = (ROOT / ".ci" / "run").read_text().strip().splitlines()
    assert ci[-1] == COMMANDS[1]  # .ci/run runs exactly the README's test command


def _python_blocks():
    """Every Python block of the README and the docs pages, as a parameter named by its page and index."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    return [pytest.param(code, id=f"{page.stem}-{i}") for page in pages
            for i, code in enumerate(re.findall(r"```python\n(.*?)```", page.read_text(), re.S))]


@pytest.mark.slow
@pytest.mark.parametrize("code", _python_blocks())
def test_every_python_block_of_the_readme_and_docs_runs_as_written(code, tmp_path):
    run = run_code(code, cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    written = [p for p in tmp_path.iterdir() if p.stat().st_size > 0]
    for name in re.findall(r"""["']([\w.-]+\.(?:vtu|png|stl|xml|igs))["']""", code):
        assert tmp_path / name in written, f"{name} was not written"  # the block wrote what it says


def _toml_blocks():
    """Every TOML block of the README and the docs pages (each a whole configuration), named like the Python ones."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    return [pytest.param(code, id=f"{page.stem}-toml-{i}") for page in pages
            for i, code in enumerate(re.findall(r"```toml\n(.*?)```", page.read_text(), re.S))]


def test_the_docs_show_configurations_to_run():
    assert len(_toml_blocks()) >= 5


@pytest.mark.slow
@pytest.mark.parametrize("code", _toml_blocks())
def test_every_toml_block_of_the_readme_and_docs_runs_through_iga_run(code, tmp_path):
    import tomllib

    (tmp_path / "case.toml").write_text(code)
    run = iga_command("--quiet", "run", "case.toml", cwd=tmp_path)
    assert run.returncode == 0, run.stderr[-2000:]
    out = tmp_path / tomllib.loads(code).get("output", {}).get("dir", "out")
    summary = json.loads((out / "summary.json").read_text())  # the run wrote what a run writes, and it holds
    if "elasticity" in summary:  # the supports carry the loads, and the work balances
        e = summary["elasticity"]
        forces = [*e["reactions_N"].values(), *e["applied_N"].values()]
        assert np.abs(np.sum(forces, axis=0)).max() <= 1e-8 * np.abs(forces).max()
        assert e["work"]["relative_error"] < 1e-9
    else:
        assert summary["connected_pieces"] == 1 and summary["energy_balance_error"] < 1e-9


def test_every_relative_link_of_the_readme_and_docs_leads_to_a_file():
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    missing = []
    for page in pages:
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", page.read_text()):
            if "://" not in target and not (page.parent / target).exists():
                missing.append(f"{page.relative_to(ROOT)} -> {target}")
    assert not missing, missing


def test_the_readme_and_docs_speak_of_the_software_not_of_its_making():
    found = [f"{page.relative_to(ROOT)}: {line.strip()[:80]}"
             for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
             for line in page.read_text().splitlines() if NARRATION.search(line)]
    assert not found, found


def test_the_code_speaks_of_the_software_not_of_its_making():
    """Docstrings and comments of the library, the benchmarks, the examples and the tests likewise (this file
    holds the pattern, so it is left out)."""
    here = Path(__file__).resolve()
    found = [f"{f.relative_to(ROOT)}:{i + 1}: {line.strip()[:80]}"
             for folder in ("geometry", "tiling", "iga", "solvers", "benchmarks", "examples", "docs", "tests")
             for f in sorted((ROOT / folder).rglob("*.py")) if f.resolve() != here
             for i, line in enumerate(f.read_text().splitlines()) if NARRATION.search(line)]
    assert not found, found
