"""The validated configuration as frozen, typed records: one dataclass per section of the schema.

:func:`iga.app.config.validate` checks a configuration and returns a :class:`Config`. Every section is a
frozen dataclass whose fields are exactly the keys of its entry in :data:`iga.app.config_schema.SCHEMA`
(``[paving]`` takes the entry of its scheme, ``paving.hierarchical``, ...), plus the few keys the validator
derives (:data:`DERIVED`); arrays of tables (``[[bc]]``) are tuples of records, lists are tuples, tables of
free keys (a tile's ``args``) :class:`FrozenTable`. Nothing in a validated configuration can be changed in
place: a changed configuration is a new one (:meth:`Record.replace`).

Sections read by attribute (``cfg.solver.tol``) and, so that code written against the validated tables keeps
working, by key (``cfg["solver"]["tol"]``, ``"h" in bc``, ``bc.get("value")``): a key is *in* a record when
the validator set it (a Neumann condition has no ``h``), while every field exists as an attribute (None when
unset). :meth:`Record.as_dict` gives the plain tables again, for ``summary.json``.
"""

from __future__ import annotations

import dataclasses

from iga.app.config_schema import SCHEMA
from iga.errors import ProblemError

__all__ = ["Record", "Config", "FrozenTable", "record", "config_record", "plain", "DERIVED", "SECTIONS"]

#: keys the validator adds to a section beyond the schema's, with what they hold
DERIVED = {
    "output": {"path": "the output folder resolved against the configuration's folder (a Path)",
               "pieces": "write this rank's VTU piece (set by the run under MPI, not by the user)"},
    "physics": {"support": "the [[support]] tables of an elastic run, validated", "load": "the [[load]] tables"},
    "tile.polygons": {"facets": "whether the polygon tile has faces (else lines only)"},
    "support": {"select": "what the support holds besides a tag: (\"edge\" | \"corner\", tags), (\"point\", xyz) or "
                          "(\"box\", (low, high))"},
}

#: the top-level sections of a validated configuration, in order
SECTIONS = ("map", "tile", "paving", "primitives", "second_level", "reduce", "physics", "material", "bc", "solver",
            "time", "adapt", "design", "output", "limits")


class Record:
    """A validated table (module notes): read by attribute, by key for the keys the validator set, frozen."""

    __slots__ = ()

    def _given(self) -> frozenset:
        return object.__getattribute__(self, "_keys")

    def __getitem__(self, key: str):
        if key not in self._given():
            raise KeyError(key)
        return getattr(self, key)

    def get(self, key: str, default=None):
        return getattr(self, key) if key in self._given() else default

    def __contains__(self, key) -> bool:
        return key in self._given()

    def __iter__(self):
        return (f.name for f in dataclasses.fields(self) if f.name in self._given())

    def __len__(self) -> int:
        return len(self._given())

    def keys(self):
        return list(iter(self))

    def values(self):
        return [getattr(self, k) for k in self]

    def items(self):
        return [(k, getattr(self, k)) for k in self]

    def replace(self, **changes) -> "Record":
        """A copy with ``changes`` (keys of this record's type), which count as set."""
        new = dataclasses.replace(self, **changes)
        object.__setattr__(new, "_keys", self._given() | frozenset(changes))
        return new

    def as_dict(self) -> dict:
        """The plain nested tables (lists for tuples, dicts for records and mappings), for JSON."""
        return {k: plain(getattr(self, k)) for k in self}


class FrozenTable(dict):
    """A table of free keys (a tile's ``args``, a map's ``channels``) that refuses changes: a ``dict`` for the
    library calls that take one, frozen like the records around it."""

    __slots__ = ()

    def _refuse(self, *args, **kwargs):
        raise TypeError("a validated configuration is frozen; build a new table instead")

    __setitem__ = __delitem__ = clear = pop = popitem = setdefault = update = __ior__ = _refuse


def plain(value):
    """``value`` of a validated configuration as plain tables: lists for tuples, dicts for records and tables."""
    if isinstance(value, Record):
        return value.as_dict()
    if isinstance(value, (tuple, list)):
        return [plain(v) for v in value]
    if isinstance(value, dict):
        return {k: plain(v) for k, v in value.items()}
    return value


def _type_name(section: str) -> str:
    return "".join(part.capitalize() for part in section.replace(".", "_").split("_")) + "Section"


def _record_type(section: str, keys) -> type:
    fields = [(k, object, dataclasses.field(default=None)) for k in keys] + [
        ("_keys", frozenset, dataclasses.field(default=frozenset(), repr=False, compare=False))]
    return dataclasses.make_dataclass(_type_name(section), fields, bases=(Record,), frozen=True,
                                      namespace={"__doc__": f"The validated [{section}] (module notes)."})


#: the record type of every section of the schema (and of the configuration itself)
TYPES = {name: _record_type(name, [k.name for k in s.keys] + list(DERIVED.get(name, {})))
         for name, s in SCHEMA.items()}
Config = _record_type("config", SECTIONS)
Config.__doc__ = "A validated configuration: one record (or tuple of records, or None) per section."

#: sections whose values hold records of other sections: (section, key) -> the inner section
_INNER = {("map", "grading"): "map.grading", ("primitive", "map"): "map", ("primitive", "tile"): "tile",
          ("second_level", "tile"): "tile", ("physics", "support"): "support", ("physics", "load"): "load"}


def _frozen(value, inner: str | None = None):
    """A validated value made immutable: tables of ``inner`` sections become records, lists tuples, other
    tables :class:`FrozenTable`."""
    if isinstance(value, dict):
        return record(inner, value) if inner else FrozenTable({k: _frozen(v) for k, v in value.items()})
    if isinstance(value, (list, tuple)):
        return tuple(_frozen(v, inner) for v in value)
    return value


def record(section: str, table: dict) -> Record:
    """The record of a validated ``table`` of schema entry ``section`` (a key outside the schema and
    :data:`DERIVED` is a bug of the validator: :class:`ProblemError` names it)."""
    kind = TYPES[section]
    names = {f.name for f in dataclasses.fields(kind)} - {"_keys"}
    extra = sorted(set(table) - names)
    if extra:
        raise ProblemError(f"the validated [{section}] holds {extra}, which its record does not declare")
    values = {k: _frozen(v, _INNER.get((section.split(".")[0], k))) for k, v in table.items()}
    return kind(**values, _keys=frozenset(table))


def _section_name(name: str, cfg: dict) -> str:
    if name == "paving":
        return f"paving.{cfg['paving']['scheme']}"
    if name == "tile" and cfg["paving"]["scheme"] == "polygons":
        return "tile.polygons"
    return {"primitives": "primitive"}.get(name, name)


def config_record(cfg: dict) -> Config:
    """The :class:`Config` of the validated tables ``cfg`` (every section of :data:`SECTIONS` present, None
    where the configuration has none)."""
    missing = [s for s in SECTIONS if s not in cfg]
    extra = sorted(set(cfg) - set(SECTIONS))
    if missing or extra:
        raise ProblemError(f"the validated configuration lacks {missing} or holds {extra}")
    values = {}
    for name in SECTIONS:
        table = cfg[name]
        section = _section_name(name, cfg)
        values[name] = None if table is None else (
            tuple(record(section, t) for t in table) if isinstance(table, list) else record(section, table))
    return Config(**values, _keys=frozenset(SECTIONS))
