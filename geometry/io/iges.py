"""IGES 5.3 export of B-spline curves, surfaces and trimmed surfaces (entities 126, 128, 142, 144).

An IGES file is 80-column records in five sections: Start (S), Global (G),
Directory Entry (D, two records per entity), Parameter Data (P, free format
in columns 1-64, the entity's D pointer in 66-72) and Terminate (T).  Every
spline is written exactly: knots, weights (1 for polynomial splines, with the
"polynomial" flag set), control points with 17 significant digits, and its
parameter range.  A :class:`geometry.shapes.trimmed.TrimmedSurface` becomes a
trimmed surface (144) on its surface (128), each loop a curve on the surface
(142) whose parameter-space curve (126, z = 0) is the loop itself.
Channels are not geometry and are left out.  Units: the
model's, declared as metres (unit flag 6) unless ``units`` says otherwise.
"""

from __future__ import annotations

import bisect
import datetime as _dt
from pathlib import Path

import numpy as np

from geometry.bspline import BSpline
from geometry.errors import SplineError, show
from geometry.io.files import atomic_write
from geometry.shapes.trimmed import TrimmedSurface

__all__ = ["write_iges", "UNITS"]

#: IGES unit flags (Global parameter 14) and names
UNITS = {"in": (1, "INCH"), "mm": (2, "MM"), "ft": (4, "FT"), "m": (6, "M"), "km": (7, "KM"), "cm": (10, "CM")}


def _check_text(what: str, text) -> None:
    """IGES strings are Hollerith fields of printable ASCII; anything else would corrupt the 80-column records."""
    if not isinstance(text, str):
        raise SplineError(f"IGES {what} must be a string, got {show(text)}")
    bad = [c for c in text if not 32 <= ord(c) <= 126]
    if bad:
        raise SplineError(f"IGES {what} {show(text)} holds {show(bad[0])}, which is not printable ASCII (IGES "
                          "records are 80 ASCII columns); use letters, digits and punctuation only")


def _hollerith(s: str) -> str:
    return f"{len(s)}H{s}"


def _num(v) -> str:
    v = float(v)
    if v == int(v) and abs(v) < 1e15:
        return f"{int(v)}."
    return repr(v).replace("e", "E")


def _records(text: str, width: int) -> list[str]:
    """Split a parameter string into chunks of at most ``width`` columns, breaking after delimiters.

    Greedy, one step per record: the token ends (after each ``,`` or ``;``)
    are found at once, and each record ends at the last of them that fits.
    """
    codes = np.frombuffer(text.encode("ascii"), np.uint8)
    ends = (np.flatnonzero((codes == ord(",")) | (codes == ord(";"))) + 1).tolist()
    if not ends or ends[-1] != len(text):
        ends.append(len(text))
    out, start = [], 0
    while start < len(text):
        j = bisect.bisect_right(ends, start + width) - 1
        stop = ends[j] if j >= 0 and ends[j] > start else min(start + width, len(text))  # one huge token: cut hard
        out.append(text[start:stop])
        start = stop
    return out


def _format(prm) -> str:
    """An entity's parameter list as IGES free-format text: integers as such, reals with 17 significant digits
    (``repr``: the shortest string that reads back to the same double), float arrays in one pass."""
    parts = []
    for v in prm:
        if isinstance(v, np.ndarray):
            parts.append(",".join(map(repr, v.astype(float).ravel().tolist())))
        elif isinstance(v, (int, np.integer)):
            parts.append(str(int(v)))
        else:
            parts.append(_num(v))
    return (",".join(parts) + ";").replace("e", "E")


def _curve(c: BSpline) -> list:
    (p,), (U,) = c.degrees, c.knots
    n = c.shape[0]
    w = np.ones(n) if c.weights is None else c.weights
    return ([126, n - 1, p, 0, 0, int(c.weights is None), 0, np.asarray(U), np.asarray(w),
             c.control_points[:, :3], float(U[0]), float(U[-1]), 0.0, 0.0, 0.0])


def _surface(s: BSpline) -> list:
    (p1, p2), (U, V) = s.degrees, s.knots
    n1, n2 = s.shape
    w = np.ones((n1, n2)) if s.weights is None else s.weights
    cp = s.control_points[..., :3]
    # IGES orders weights and points with the first index fastest
    return ([128, n1 - 1, n2 - 1, p1, p2, 0, 0, int(s.weights is None), 0, 0, np.asarray(U), np.asarray(V),
             w.T, np.transpose(cp, (1, 0, 2)), float(U[0]), float(U[-1]), float(V[0]), float(V[-1])])


def _entities(items) -> tuple[list, list]:
    """(parameter list, directory-entry status digits) per IGES entity of the curves, surfaces and trimmed
    surfaces ``items``; a directory entry's sequence number is 2 x its index + 1."""
    params, status = [], []  # per entity: parameter list, DE status digits

    def add(prm, st="00000000") -> int:
        params.append(prm)
        status.append(st)
        return 2 * len(params) - 1  # its directory entry's sequence number

    for i, s in enumerate(items):
        if isinstance(s, TrimmedSurface):
            S = add(_surface(s.surface), "00010000")  # physically dependent on the 144
            bounds = []
            for c in s.loops:
                curve = add(_curve(c), "00010500")  # parameter-space curve: dependent, "parametric" use
                bounds.append(add([142, 1, S, curve, 0, 1], "00010000"))
            add([144, S, 1, len(bounds) - 1] + bounds)
            continue
        if not isinstance(s, BSpline) or s.dim not in (1, 2):
            raise SplineError(f"item {i} is {show(s)}: IGES export takes B-spline curves and surfaces (entities "
                              "126, 128) and trimmed surfaces (144); write a trivariate's boundary surfaces instead")
        if not np.all(np.isfinite(s.control_points)):
            raise SplineError(f"item {i} has non-finite control points; IGES cannot hold them")
        add(_curve(s) if s.dim == 1 else _surface(s))
    return params, status


def _sections(gtext: str, params: list, status: list) -> list[str]:
    """The 80-column records of the start, global, directory, parameter and terminate sections."""
    s_lines = ["IGES export of exact B-spline geometry (iga-microstructures)"]
    g_lines = _records(gtext, 72)
    d_lines, p_lines = [], []
    for i, prm in enumerate(params):
        de = 2 * i + 1
        chunk = _records(_format(prm), 64)
        start = len(p_lines) + 1
        p_lines += [f"{c:<64} {de:>7}" for c in chunk]
        etype = prm[0]
        d_lines.append(f"{etype:>8}{start:>8}{0:>8}{0:>8}{0:>8}{0:>8}{0:>8}{0:>8}{status[i]:>8}")
        d_lines.append(f"{etype:>8}{0:>8}{0:>8}{len(chunk):>8}{0:>8}{'':>8}{'':>8}{'':>8}{0:>8}")
    records = ([f"{x:<72}S{k + 1:>7}" for k, x in enumerate(s_lines)]
               + [f"{x:<72}G{k + 1:>7}" for k, x in enumerate(g_lines)]
               + [f"{x:<72}D{k + 1:>7}" for k, x in enumerate(d_lines)]
               + [f"{x:<72}P{k + 1:>7}" for k, x in enumerate(p_lines)])
    counts = f"S{len(s_lines):>7}G{len(g_lines):>7}D{len(d_lines):>7}P{len(p_lines):>7}"
    records.append(f"{counts:<72}T{1:>7}")
    if any(len(r) != 80 for r in records):  # a fixed format: never write a record another reader cannot take
        bad = next(k for k, r in enumerate(records) if len(r) != 80)
        raise SplineError(f"IGES record {bad + 1} would have {len(records[bad])} columns instead of 80; nothing "
                          "was written (please report this)")
    return records


def write_iges(path, splines, *, units: str = "m", author: str = "iga-microstructures", name: str = "") -> Path:
    """Write B-spline curves (126), surfaces (128) and trimmed surfaces (144) to an IGES file (atomic).

    ``splines``: geometry.BSpline curves and surfaces and
    :class:`geometry.shapes.trimmed.TrimmedSurface` (trivariates: write their
    boundary surfaces, e.g. ``[v.boundary(f) for f in FACE_NAMES]``).
    """
    items = list(splines)
    if not items:
        raise SplineError("write_iges needs at least one curve or surface")
    if units not in UNITS:
        raise SplineError(f"units must be one of {sorted(UNITS)}, got {show(units)}")
    path = Path(path)
    for what, text in (("name", name), ("author", author), ("the file name", path.name)):
        _check_text(what, text)
    params, status = _entities(items)
    stamp = _dt.datetime.now().strftime("%Y%m%d.%H%M%S")
    flag, unit = UNITS[units]
    extent = max(float(np.abs((s.surface if isinstance(s, TrimmedSurface) else s).control_points[..., :3]).max())
                 for s in items)
    glob = [",", ";", name or path.stem, path.name, "iga-microstructures", "1", 32, 38, 6, 308, 15,
            name or path.stem, 1.0, flag, unit, 1, 1.0, stamp, 1e-10, max(extent, 1.0), author, "iga", 11, 0, stamp]
    gtext = ",".join(_hollerith(v) if isinstance(v, str) else (str(v) if isinstance(v, int) else _num(v))
                     for v in glob) + ";"
    records = _sections(gtext, params, status)
    text = "\n".join(records) + "\n"

    def write(tmp):
        Path(tmp).write_text(text, encoding="ascii")

    return atomic_write(path, write, ".igs")
