"""A validated configuration is frozen records: one dataclass per schema section, read by attribute and by key."""

import dataclasses
import json

import pytest

from iga import ProblemError
from iga.app.config import validate
from iga.app.config_records import DERIVED, TYPES, Config, Record, plain, record
from iga.app.config_schema import SCHEMA
from iga.app.pipeline import heat_sink_config


@pytest.fixture(scope="module")
def cfg(tmp_path_factory):
    return validate(heat_sink_config("vertical", stress=True), tmp_path_factory.mktemp("cfg"))


def test_every_section_s_record_declares_exactly_the_schema_s_keys_and_the_derived_ones():
    assert set(TYPES) == set(SCHEMA)
    for name, section in SCHEMA.items():
        fields = [f.name for f in dataclasses.fields(TYPES[name]) if f.name != "_keys"]
        assert fields == [k.name for k in section.keys] + list(DERIVED.get(name, {})), name
        assert TYPES[name].__dataclass_params__.frozen


def test_a_validated_configuration_cannot_be_changed_in_place(cfg):
    assert isinstance(cfg, Config) and isinstance(cfg.solver, Record)
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.solver.tol = 1.0
    with pytest.raises(TypeError):
        cfg["solver"]["tol"] = 1.0
    with pytest.raises(TypeError, match="frozen"):
        cfg.map.args["size"] = 1.0
    assert isinstance(cfg.bc, tuple) and isinstance(cfg.paving.counts, tuple)
    changed = cfg.solver.replace(tol=1e-6)
    assert changed.tol == 1e-6 and cfg.solver.tol == 1e-10 and changed.method == cfg.solver.method


def test_attributes_and_keys_read_the_same_and_only_set_keys_are_in_a_record(cfg):
    neumann, robin = cfg.bc
    assert neumann.kind == neumann["kind"] == "neumann" and robin["h"] == robin.h == 5.0
    assert "h" not in neumann and neumann.h is None and neumann.get("h", 3.0) == 3.0
    with pytest.raises(KeyError):
        neumann["h"]
    assert list(neumann) == ["kind", "tag", "value"] and dict(neumann.items()) == neumann.as_dict()
    assert cfg.paving.scheme == "hierarchical" and type(cfg.paving).__name__ == "PavingHierarchicalSection"
    assert cfg.physics.kind == "thermo-elastic" and cfg.time is None


def test_the_plain_tables_are_what_json_takes(cfg):
    tables = cfg.as_dict()
    text = json.dumps(tables, default=str)
    assert json.loads(text)["bc"][1] == {"kind": "robin", "tag": "exterior", "h": 5.0, "ambient": 30.0}
    assert plain(cfg.paving.counts) == [4, 4] and tables["output"]["name"] == "heat_sink"


def test_a_key_the_validator_does_not_declare_is_named():
    with pytest.raises(ProblemError, match=r"\[solver\] holds \['colour'\]"):
        record("solver", {"method": "auto", "colour": 1})
