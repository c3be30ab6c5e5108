"""What ``iga info`` says about the files the toolkit writes besides splines: meshes (VTU, VTP, STL, OBJ,
PLY), IGES files and the pipeline's ``summary.json``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from iga.errors import ProblemError

__all__ = ["MESH_SUFFIXES", "describe"]

MESH_SUFFIXES = (".vtu", ".vtp", ".vtk", ".stl", ".obj", ".ply")
_IGES_NAMES = {126: "B-spline curves", 128: "B-spline surfaces", 142: "curves on surfaces", 144: "trimmed surfaces"}


def describe(path: Path) -> list[str] | None:
    """Lines describing ``path``, or None when it is not one of these kinds (a spline file)."""
    suffix = path.suffix.lower()
    if suffix in MESH_SUFFIXES:
        return _mesh(path)
    if suffix in (".igs", ".iges"):
        return _iges(path)
    if suffix == ".json":
        return _summary(path)
    return None


def _mesh(path: Path) -> list[str]:
    import pyvista as pv

    try:
        mesh = pv.read(path)
    except Exception as exc:  # VTK and meshio raise many kinds for a damaged file
        raise ProblemError(f"cannot read {path.name} as a mesh: {exc}") from None
    if mesh.n_points == 0:
        raise ProblemError(f"cannot read {path.name} as a mesh: it holds no points (damaged, or not a mesh file)")
    conn = np.asarray(mesh.cast_to_unstructured_grid().cell_connectivity) if mesh.n_cells else np.zeros(0, int)
    if conn.size and (conn.min() < 0 or conn.max() >= mesh.n_points):
        bad = int(conn.max() if conn.max() >= mesh.n_points else conn.min())
        raise ProblemError(f"{path.name} is damaged: a cell names point {bad + 1} (counting from 1, as OBJ does) "
                           f"but the file has {mesh.n_points:,} points; repair or re-export the mesh")
    types = {}
    if mesh.n_cells:
        names = {12: "hexahedra", 79: "Bezier hexahedra", 5: "triangles", 9: "quads", 10: "tetrahedra"}
        celltypes = mesh.celltypes if hasattr(mesh, "celltypes") else mesh.cast_to_unstructured_grid().celltypes
        kinds, counts = np.unique(celltypes, return_counts=True)
        types = {names.get(int(k), f"cells of VTK type {int(k)}"): int(c) for k, c in zip(kinds, counts)}
    cells = ", ".join(f"{c:,} {k}" for k, c in types.items()) or f"{mesh.n_cells:,} cells"
    lo, hi = np.asarray(mesh.bounds[::2]), np.asarray(mesh.bounds[1::2])
    out = [f"{path.name}: {mesh.n_points:,} points, {cells}; bounding box {np.round(lo, 6).tolist()} .. "
           f"{np.round(hi, 6).tolist()}"]
    for where, data in (("point", mesh.point_data), ("cell", mesh.cell_data)):
        for name in data.keys():
            v = np.asarray(data[name], float)
            if v.size == 0:
                continue
            comps = "" if v.ndim == 1 else f" ({v.shape[1]} components)"
            finite = v[np.isfinite(v)]
            rng = f"{finite.min():.6g} .. {finite.max():.6g}" if finite.size else "no finite values"
            out.append(f"   {where} array {name}{comps}: {rng}")
    return out


def _iges(path: Path) -> list[str]:
    try:
        lines = path.read_text(encoding="ascii").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise ProblemError(f"cannot read {path.name} as IGES (fixed-format ASCII): {exc}") from None
    sections = {k: [ln for ln in lines if len(ln) >= 73 and ln[72] == k] for k in "SGDPT"}
    if not sections["D"] or not sections["T"]:
        raise ProblemError(f"{path.name} is not an IGES file: it has no directory or terminate section "
                           "(80-column records ending in D and T)")
    kinds: dict = {}
    for rec in sections["D"][::2]:  # two directory records per entity; the first holds its type
        try:
            t = int(rec[:8])
        except ValueError:
            raise ProblemError(f"{path.name}: a directory record does not start with an entity type: {rec[:16]!r}") \
                from None
        kinds[t] = kinds.get(t, 0) + 1
    listed = ", ".join(f"{n} {_IGES_NAMES.get(t, f'entities of type {t}')}" for t, n in sorted(kinds.items()))
    return [f"{path.name}: IGES, {sum(kinds.values())} entities ({listed}); {len(sections['P'])} parameter records"]


def _summary(path: Path) -> list[str]:
    try:
        s = json.loads(path.read_text())
    except RecursionError:  # thousands of nested brackets
        raise ProblemError(f"cannot read {path.name} as a pipeline summary: its JSON is nested too deeply") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ProblemError(f"cannot read {path.name} as a pipeline summary (JSON): {exc}") from None
    if not isinstance(s, dict) or "tiles" not in s:
        raise ProblemError(f"{path.name} is JSON but not a pipeline summary (no 'tiles' entry)")
    try:
        return _summary_lines(path.name, s)
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:  # a hand-edited or foreign file
        raise ProblemError(f"{path.name} is not laid out as a pipeline summary ({type(exc).__name__}: {exc}); "
                           "describe the summary.json that iga run or iga demo wrote") from None


def _summary_lines(name: str, s: dict) -> list[str]:
    """The description of a parsed summary (raises KeyError, TypeError... where its layout is not the
    pipeline's: the caller reports it as the project's error)."""
    out = [f"{name}: pipeline summary, {s['tiles']} tiles on {s.get('levels', '?')} levels, "
           f"{s.get('interfaces', '?')} interfaces"]
    if "temperature_C" in s:
        t = s["temperature_C"]
        out.append(f"   heat: {s['dofs']} DOFs, temperature {t['min']:.4g} .. {t['max']:.4g} (mean {t['mean']:.4g}), "
                   f"inflow {s['inflow_W']:.4g} W, balance error {s['energy_balance_error']:.1e}")
    if "elasticity" in s:
        e = s["elasticity"]
        out.append(f"   elasticity: {e['dofs']} DOFs, largest displacement {e['max_displacement_m']:.3g} m, von Mises "
                   f"up to {e['max_von_mises_Pa']:.3g} Pa, work balance error {e['work']['relative_error']:.1e}")
    for kind, name in s.get("files", {}).items():
        out.append(f"   {kind}: {name}")
    return out
