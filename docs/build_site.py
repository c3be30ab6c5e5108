"""Build the documentation site: write ``docs/pipeline-reference.md`` from the validator's table
(:mod:`iga.app.config_schema`), run every gallery script of ``examples/`` (each writes its picture into
``docs/gallery/``), write ``docs/gallery.md`` from their docstrings, pictures and printed output, then
``mkdocs build --strict`` (warnings are errors) into ``site/``.

    python docs/build_site.py [--no-examples] [--site-dir DIR]

``--no-examples`` keeps the pictures already in ``docs/gallery/`` (the site alone, in seconds).  Needs the
``[docs]`` extra (mkdocs, mkdocstrings).
"""

from __future__ import annotations

import argparse
import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
GALLERY = ROOT / "docs" / "gallery"


def examples() -> list[Path]:
    """The gallery's scripts, in name order."""
    return sorted(EXAMPLES.glob("*.py"))


def run_example(script: Path, out: Path) -> str:
    """Run one gallery script writing its picture into ``out``; returns what it printed."""
    run = subprocess.run([sys.executable, str(script), str(out)], capture_output=True, text=True, cwd=out)
    if run.returncode:
        raise SystemExit(f"{script.name} failed:\n{run.stderr[-3000:]}")
    return run.stdout.strip()


def gallery_page(printed: dict) -> str:
    """docs/gallery.md: per script its title and case (the docstring), its picture and what it printed; the
    scripts named ``paper_*`` (figures of the three papers, reproduced) in a section of their own."""
    lines = ["# Gallery", "", "Each picture comes from a script under `examples/` that states its case; "
             "`python docs/build_site.py` runs them all (`python examples/NAME.py OUT_DIR` runs one).", ""]
    groups = (("Analyses and structures", [s for s in examples() if not s.stem.startswith("paper_")]),
              ("Figures of the papers, reproduced", [s for s in examples() if s.stem.startswith("paper_")]))
    for heading, scripts in groups:
        lines += [f"## {heading}", ""]
        for script in scripts:
            doc = ast.get_docstring(ast.parse(script.read_text())) or script.stem
            title, _, case = doc.partition("\n")
            lines += [f"### {title.rstrip('.')}", "", case.strip(), "", f"![{title}](gallery/{script.stem}.png)", "",
                      f"`examples/{script.name}` prints:", "", "```text",
                      printed.get(script.stem, "").strip() or "-", "```", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-examples", action="store_true", help="keep the pictures in docs/gallery")
    ap.add_argument("--site-dir", default=str(ROOT / "site"), help="where the site is written")
    args = ap.parse_args(argv)
    page = ROOT / "docs" / "gallery.md"
    sys.path.insert(0, str(ROOT))
    from iga.app.config_schema import reference

    (ROOT / "docs" / "pipeline-reference.md").write_text(reference())
    if not args.no_examples:
        GALLERY.mkdir(exist_ok=True)
        printed = {}
        for script in examples():
            print(f"running {script.name}", flush=True)
            printed[script.stem] = run_example(script, GALLERY)
        page.write_text(gallery_page(printed))
    missing = [s.name for s in examples() if not (GALLERY / f"{s.stem}.png").exists()]
    if missing:
        raise SystemExit(f"no picture for {missing}; run without --no-examples")
    build = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-f", str(ROOT / "mkdocs.yml"),
                            "-d", args.site_dir], cwd=ROOT)
    return build.returncode


if __name__ == "__main__":
    raise SystemExit(main())
