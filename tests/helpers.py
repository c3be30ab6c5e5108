"""Random spline factories shared by the tests."""

import re
from contextlib import contextmanager

import numpy as np

from geometry import BSpline


def random_knots(rng, p, n_inner_max=3, lo=0.0, hi=1.0, max_mult=None):
    """Open knot vector with random interior knots (multiplicity 1..max_mult)."""
    max_mult = p if max_mult is None else max_mult
    k = int(rng.integers(0, n_inner_max + 1))
    vals = np.sort(rng.uniform(lo, hi, k))
    vals = vals[np.diff(np.r_[lo, vals]) > 0.05 * (hi - lo)]
    vals = vals[(hi - vals) > 0.05 * (hi - lo)]
    mults = rng.integers(1, max_mult + 1, len(vals))
    return np.concatenate([np.full(p + 1, lo), np.repeat(vals, mults), np.full(p + 1, hi)])


def random_spline(rng, dim, degrees=None, rational=False, channels=(), n_inner_max=3, max_p=5, domain=None):
    degrees = tuple(int(rng.integers(1, max_p + 1)) for _ in range(dim)) if degrees is None else tuple(degrees)
    domain = [(0.0, 1.0)] * dim if domain is None else domain
    knots = [random_knots(rng, p, n_inner_max, *domain[k]) for k, p in enumerate(degrees)]
    shape = tuple(len(U) - p - 1 for U, p in zip(knots, degrees))
    cp = rng.uniform(-1, 1, shape + (3 + len(channels),))
    w = rng.uniform(0.5, 2.0, shape) if rational else None
    return BSpline(degrees, knots, cp, w, channels)


def random_points(rng, spline, n=1000):
    dom = spline.domain
    return dom[:, 0] + rng.random((n, spline.dim)) * (dom[:, 1] - dom[:, 0])


def rel_err(a, b):
    return np.abs(a - b).max() / max(1.0, np.abs(b).max())


def surface_gauss(surface, n=8):
    """Gauss-Legendre points (M, 2) and weights (M,), n per knot span and direction, on any surface's domain."""
    pts, wts = [], []
    x, w = np.polynomial.legendre.leggauss(n)
    for k in range(2):
        b = surface.breakpoints(k)
        h = np.diff(b)
        pts.append((b[:-1, None] + h[:, None] * (x + 1) / 2).ravel())
        wts.append((h[:, None] * w / 2).ravel())
    return np.stack(np.meshgrid(*pts, indexing="ij"), -1).reshape(-1, 2), np.multiply.outer(*wts).ravel()


def surface_area(surface, n=8):
    """Area of a spline surface by Gauss-Legendre quadrature (n points per knot span and direction).

    Independent of the analysis code: only the surface's own Jacobian is used.
    """
    g, W = surface_gauss(surface, n)
    J = surface.jacobian(g)[:, :3, :]
    return float(np.sum(np.linalg.norm(np.cross(J[:, :, 0], J[:, :, 1]), axis=1) * W))


def read_own_iges(path):
    """A minimal reader of our own IGES output: checks the record layout, returns the parameter lists."""
    lines = path.read_text().splitlines()
    assert all(len(x) == 80 for x in lines)
    sections = {k: [x for x in lines if x[72] == k] for k in "SGDPT"}
    term = sections["T"][0]
    counts = dict(re.findall(r"([SGDP])\s*(\d+)", term[:72]))
    assert all(int(counts[k]) == len(sections[k]) for k in "SGDP")
    d = sections["D"]
    out = []
    for i in range(0, len(d), 2):
        etype, start = int(d[i][:8]), int(d[i][8:16])
        count = int(d[i + 1][24:32])
        data = "".join(x[:64] for x in sections["P"][start - 1:start - 1 + count])
        assert all(int(x[64:72]) == i + 1 for x in sections["P"][start - 1:start - 1 + count])  # back pointers
        values = [float(v) for v in data.rstrip().rstrip(";").split(",")]
        assert int(values[0]) == etype
        out.append(values)
    return out


def decode_appended_vtu(path) -> dict:
    """Every DataArray of a VTU with appended binary data, raw or zlib-compressed, with UInt32 or UInt64 block
    headers (as its VTKFile element says), by name: a reader of our own, written from VTK's file format."""
    import xml.etree.ElementTree as ET
    import zlib

    raw = path.read_bytes()
    start = raw.index(b"<AppendedData")
    head = ET.fromstring(raw[:start].decode() + "</VTKFile>")
    word = "<u8" if head.get("header_type") == "UInt64" else "<u4"
    w = np.dtype(word).itemsize
    compressed = head.get("compressor") == "vtkZLibDataCompressor"
    data = raw[raw.index(b"_", start) + 1:]
    dtypes = {"Float64": "<f8", "Float32": "<f4", "Int32": "<i4", "Int64": "<i8", "UInt8": "u1"}
    out = {}
    for el in head.iter("DataArray"):
        off = int(el.get("offset"))
        if not compressed:  # one header word: the byte count, then the values
            nbytes = int(np.frombuffer(data[off:off + w], word)[0])
            out[el.get("Name")] = np.frombuffer(data[off + w:off + w + nbytes], dtypes[el.get("type")])
            continue
        nb = int(np.frombuffer(data[off:off + w], word)[0])  # blocks, block size, last block size, sizes
        sizes = np.frombuffer(data[off + 3 * w:off + 3 * w + w * nb], word)
        pos, chunks = off + 3 * w + w * nb, []
        for size in sizes:
            chunks.append(zlib.decompress(data[pos:pos + int(size)]))
            pos += int(size)
        out[el.get("Name")] = np.frombuffer(b"".join(chunks), dtypes[el.get("type")])
    return out


def face_params(P, face, st):
    """Parameters (N, 3) of placed patch P on its face ``face`` at normalised face parameters st (N, 2) in
    [0, 1]^2 (the face's two remaining directions, in order)."""
    from geometry.faces import FACE_AXIS

    k, side = FACE_AXIS[face]
    dom = P.spline.domain
    rest = [d for d in range(3) if d != k]
    x = np.empty((len(st), 3))
    x[:, k] = dom[k, side]
    x[:, rest] = dom[rest, 0] + np.asarray(st) * np.ptp(dom[rest], axis=1)
    return x


@contextmanager
def opencascade(path):
    """A second reader for IGES: gmsh's OpenCASCADE import of ``path``; yields ``(gmsh, face tags)`` and
    finalises gmsh after (the test is skipped where gmsh is not installed)."""
    import pytest

    gmsh = pytest.importorskip("gmsh")
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.occ.importShapes(str(path))
        gmsh.model.occ.synchronize()
        yield gmsh, [t for _, t in gmsh.model.getEntities(2)]
    finally:
        gmsh.finalize()


def vtk_cell_values(grid, rng, n_cells=4, n_points=4, field="temperature"):
    """Locations and point-data values (``field``) that VTK itself evaluates inside random cells."""
    import vtk

    xs, ts = [], []
    for ci in rng.choice(grid.n_cells, min(n_cells, grid.n_cells), replace=False):
        cell = grid.GetCell(int(ci))
        ids = [cell.GetPointId(i) for i in range(cell.GetNumberOfPoints())]
        for _ in range(n_points):
            x, w = [0.0, 0.0, 0.0], np.zeros(len(ids))
            cell.EvaluateLocation(vtk.reference(0), list(rng.random(3)), x, w)
            xs.append(x)
            ts.append(float(w @ grid.point_data[field][ids]))
    return np.array(xs), np.array(ts)
