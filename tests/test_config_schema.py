"""The pipeline reference and the validator read one table (iga.app.config_schema): the page the docs show is the
table, every section refuses a key the table does not list (naming the keys it does), and every default the
reference states is the value the validator fills in."""

import copy
from pathlib import Path

import pytest

from iga import ProblemError
from iga.app.config import validate
from iga.app.config_records import plain
from iga.app.config_schema import REQUIRED, SCHEMA, allowed, reference

ROOT = Path(__file__).resolve().parents[1]
HEAT = {"map": {"primitive": "box"}, "tile": {"library": "cross"}, "paving": {"scheme": "regular", "counts": [1, 1, 1]},
        "bc": [{"kind": "dirichlet", "tag": "umin", "value": 1.0}]}
ELASTIC = {**HEAT, "bc": None, "physics": {"kind": "elasticity", "youngs": 1.0, "poisson": 0.3},
           "support": [{"tag": "umin"}], "load": [{"kind": "pressure", "tag": "umax", "value": 1.0}]}
VREP = {"paving": {"scheme": "vrep", "expression": "A"},
        "primitive": [{"name": "A", "map": {"primitive": "box"}, "tile": {"library": "cross"}, "counts": [1, 1, 1]}],
        "bc": [{"kind": "dirichlet", "tag": "A", "value": 1.0}]}


#: defaults that apply to one variant of a section, not to the base configuration of the test
_ELSEWHERE = {("bc", "scale"), ("physics", "reference"), ("design", "hold"), ("design", "axes")}  # hold, axes: a shape design's


def _config(section: str) -> tuple[dict, callable, callable]:
    """A valid configuration that holds ``section``, a function giving the section's table inside it (to add a
    key to) and one giving the validated section (to read a default from)."""
    cfg = copy.deepcopy(ELASTIC if section in ("physics", "support", "load") else HEAT)
    cfg = {k: v for k, v in cfg.items() if v is not None}
    at, out = None, None
    if section in ("map", "tile", "material", "output", "solver", "limits"):
        cfg.setdefault(section, {})
        at, out = (lambda c: c[section]), (lambda v: v[section])
    elif section == "map.grading":
        cfg["map"]["grading"] = {}
        at, out = (lambda c: c["map"]["grading"]), (lambda v: v["map"]["grading"][0])
    elif section == "tile.polygons":
        cfg.update(tile={"points": [[0, 0, 0], [1, 1, 1]], "lines": [[0, 1]]},
                   paving={"scheme": "polygons", "counts": [1, 1, 1]})
        del cfg["bc"]
        at, out = (lambda c: c["tile"]), (lambda v: v["tile"])
    elif section.startswith("paving."):
        scheme = section.split(".")[1]
        paving = {"regular": {"counts": [1, 1, 1], "seal": "cap"}, "hierarchical": {"counts": [1, 1], "seal": "cap"},
                  "bifurcation": {"epsilon": 1.0}, "polygons": {"counts": [1, 1, 1]},
                  "field_graded": {"counts": [1, 1, 1], "field": 0.3},
                  "random_implicit": {"counts": [1, 1, 1]}, "implicit_bifurcation": {"epsilon": 1.0}}
        if scheme == "vrep":
            cfg = copy.deepcopy(VREP)
        else:
            cfg["paving"] = {"scheme": scheme, **paving[scheme]}
        if scheme in ("bifurcation", "random_implicit", "implicit_bifurcation"):
            del cfg["tile"]
        if scheme == "polygons":
            cfg["tile"] = {"library": "beam_lattice"}
        if scheme == "field_graded":
            cfg["tile"] = {"library": "face_graded_cross"}
        if scheme in ("polygons", "random_implicit", "implicit_bifurcation"):
            del cfg["bc"]
        at, out = (lambda c: c["paving"]), (lambda v: v["paving"])
    elif section == "primitive":
        cfg = copy.deepcopy(VREP)
        at, out = (lambda c: c["primitive"][0]), (lambda v: v["primitives"][0])
    elif section in ("second_level", "reduce"):
        cfg[section] = ({"tile": {"library": "cross"}, "counts": [1, 1, 1]} if section == "second_level"
                        else {"degree": 2})
        at, out = (lambda c: c[section]), (lambda v: v[section])
    elif section in ("bc", "support", "load"):
        at, out = (lambda c: c[section][0]), (lambda v: (v if section == "bc" else v["physics"])[section][0])
    elif section == "physics":
        at, out = (lambda c: c["physics"]), (lambda v: v["physics"])
    elif section == "adapt":
        cfg["adapt"] = {"tolerance": 0.01}
        at, out = (lambda c: c["adapt"]), (lambda v: v["adapt"])
    elif section == "design":
        cfg.update(map={"primitive": "box", "grading": {"channel": "k", "near": 100.0, "far": 100.0, "face": "wmin"}},
                   material={"conductivity": "k"}, design={"variables": "channel:k", "bounds": [54.0, 205.0]})
        at, out = (lambda c: c["design"]), (lambda v: v["design"])
    elif section == "time":
        cfg.update(physics={"kind": "transient-heat"}, material={"capacity": 1.0}, time={"end": "steady", "tolerance": 0.1})
        at, out = (lambda c: c["time"]), (lambda v: v["time"])
    return cfg, at, out


def test_the_pipeline_reference_page_is_the_validators_table():
    page = (ROOT / "docs" / "pipeline-reference.md").read_text()
    assert page == reference(), "docs/pipeline-reference.md is stale: python -m iga.app.config_schema > it"
    for section in SCHEMA.values():  # every key is on the page, in its section's table
        part = page.split(f"## {section.title}\n", 1)[1].split("\n## ", 1)[0]
        assert all(f"| `{k.name}` |" in part for k in section.keys), section.name


@pytest.mark.parametrize("section", sorted(SCHEMA))
def test_every_section_refuses_a_key_the_reference_does_not_list(section, tmp_path):
    cfg, at, _ = _config(section)
    validate(cfg, tmp_path)  # the base configuration holds
    at(cfg)["colour"] = 1
    with pytest.raises(ProblemError) as err:
        validate(cfg, tmp_path)
    message = str(err.value)
    assert "colour" in message
    assert message.split("allowed keys:")[1].strip() == str(sorted(allowed(section)))  # what the reference lists


@pytest.mark.parametrize("section", sorted(SCHEMA))
def test_every_default_the_reference_states_is_the_one_the_validator_fills_in(section, tmp_path):
    cfg, at, out = _config(section)
    table = at(cfg)
    checked = 0
    for key in SCHEMA[section].keys:
        if key.default is REQUIRED or key.default is None or key.name in table:
            continue
        got = out(validate(cfg, tmp_path))
        if (section, key.name) in _ELSEWHERE:
            assert key.name not in got
            continue
        expected = key.default
        if section == "second_level" and key.name == "degree":
            expected = 2
        assert plain(got[key.name]) == expected, \
            f"{section}.{key.name}: validator {got[key.name]!r}, reference {expected!r}"
        checked += 1
    defaults = [k for k in SCHEMA[section].keys if k.default is not REQUIRED and k.default is not None
                and (section, k.name) not in _ELSEWHERE and k.name not in table]
    assert checked == len(defaults)


def test_keys_of_another_scheme_are_refused_naming_the_schemes_that_take_them(tmp_path):
    cfg, _, _ = _config("paving.regular")
    cfg["paving"]["radius"] = 0.3
    with pytest.raises(ProblemError, match=r"paving\.radius: applies to the implicit_bifurcation scheme only"):
        validate(cfg, tmp_path)
    cfg, _, _ = _config("paving.bifurcation")
    cfg["paving"]["alpha"] = 0.3  # a key of the implicit schemes and of vrep, not of bifurcation
    with pytest.raises(ProblemError, match=r"paving\.alpha: does not apply to the bifurcation scheme"):
        validate(cfg, tmp_path)
