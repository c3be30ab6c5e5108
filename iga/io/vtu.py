"""VTU export (ParaView / VTK) of models and solutions.

``cells="linear"``: every patch sampled on conforming grids of linear
hexahedra (VTK type 12) and welded into one mesh without internal faces
(:mod:`iga.io.sampling`).  Point data: ``temperature`` (with a heat solution),
``heat_flux`` (W/m^2, vector), ``conductivity`` (a scalar, or the 3 x 3 tensor);
``displacement`` (m, vector: ParaView's Warp By Vector), ``stress`` (Pa, xx, yy, zz,
xy, xz, yz), ``von_mises`` (Pa), ``youngs_modulus`` and ``poisson_ratio`` (with an
elastic solution; ``cubic_constants`` C11, C12, C44 in Pa for a cubic material); and every channel of the tiles and the deformation map; cell data: ``patch``,
``tile`` and ``level`` (filter by level in ParaView with Threshold).

``cells="bezier"``: one exact rational Bezier hexahedron (VTK type 79) per
element (:mod:`iga.io.vtu_bezier`).

Files are written by VTK's XML writer with appended binary data, raw by default
or zlib-compressed (``compress=True``; meshio, VTK, ParaView and pyvista read
both, and VTK's LZ4 is faster but meshio cannot decode it: :func:`save_grid`
says what each costs), to a temporary name renamed into place (atomic).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from geometry.io.files import atomic_write, check_folder

from iga.errors import ProblemError
from iga.model import as_model
from iga.elasticity.solution import ElasticSolution
from iga.io.sampling import displacement_fields, temperature_fields
from iga.heat.solution import Solution
from iga.io.grids import sample_grid
from iga.io.vtu_bezier import bezier_grid
from geometry.errors import show
from geometry.numbers import is_integer, is_real

__all__ = ["write_vtu", "write_pieces", "save_grid", "save_vtu"]


def save_grid(grid, path, compress: bool = False) -> None:
    """Write a pyvista/VTK unstructured grid as XML (.vtu) with its arrays appended as raw binary (64-bit block
    headers), or zlib-compressed at level 1 with ``compress``.

    Measured on the circular demo sink at ``--refine 2`` (1.5 million points, 1.3 million hexahedra, four
    point arrays; ``python benchmarks/output_speed.py``): raw 0.1 s and 210 MiB; zlib level 1 3.1 s and 83 MiB;
    VTK's default zlib level 4.9 s and 79 MiB; LZ4 0.24 s and 109 MiB, but meshio cannot read LZ4. VTK
    compresses on one thread at about 50 MB/s, so compressing costs more than the analysis: raw is the
    default, zlib (every reader has it) the choice for files to keep."""
    # the XML writer's module alone: ``import vtk`` loads every VTK module (0.7 s, more than writing a million
    # points), the writer's 0.01 s
    from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridWriter

    writer = vtkXMLUnstructuredGridWriter()
    writer.SetFileName(str(path))
    writer.SetInputData(grid)
    writer.SetDataModeToAppended()
    writer.EncodeAppendedDataOff()
    writer.SetHeaderTypeToUInt64()  # raw arrays of 4 GiB and more have a size that fits
    if compress:
        writer.SetCompressorTypeToZLib()
        writer.SetCompressionLevel(1)
    else:
        writer.SetCompressorTypeToNone()
    if not writer.Write():
        raise OSError(f"VTK could not write {path}")


def save_vtu(path, grid, compress: bool = False) -> Path:
    """``grid`` written to ``path`` by :func:`save_grid` under a temporary name renamed into place (atomic)."""
    return atomic_write(path, lambda tmp: save_grid(grid, tmp, compress), ".vtu", ProblemError)


def write_vtu(path, solution_or_model, samples: int = 3, cells: str = "linear", tolerance: float | None = None,
              compress: bool = False) -> Path:
    """Write one ``.vtu`` file with every patch of a model or solution.

    Parameters
    ----------
    path : output file (``.vtu``); its folder must exist and be writable
    solution_or_model : :class:`iga.Solution`, :class:`iga.ElasticSolution`, or anything
        :func:`iga.model.as_model` accepts
    samples : subdivisions of every element per direction (>= 1), for ``cells="linear"``
    tolerance : with ``cells="linear"``, the largest distance (model units) of the written cells from the exact
        geometry: the samples per element are chosen per patch and direction to meet it (up to 32), instead of
        ``samples``
    cells : ``"linear"`` (sampled linear hexahedra, with heat flux) or ``"bezier"``: one exact
        rational Bezier hexahedron (VTK type 79) per element, geometry and temperature exact
        (:mod:`iga.io.vtu_bezier`; composes every patch, so heavier for large models)
    compress : zlib-compress the arrays (level 1): files about 2.5 times smaller, written about 30 times slower
        (:func:`save_grid`)

    >>> import pyvista as pv, tempfile, os
    >>> from geometry import primitives
    >>> from iga import HeatProblem
    >>> sol = HeatProblem(primitives.box()).dirichlet("umin", 0.0).dirichlet("umax", 1.0).solve()
    >>> path = write_vtu(os.path.join(tempfile.mkdtemp(), "cube.vtu"), sol, samples=2)
    >>> grid = pv.read(path)
    >>> grid.n_cells, round(float(grid.point_data["temperature"].max()), 12)
    (8, 1.0)
    """
    if not is_integer(samples) or samples < 1:
        raise ProblemError(f"samples must be a positive integer, got {show(samples)}")
    if tolerance is not None and not (is_real(tolerance)
                                      and np.isfinite(tolerance) and tolerance > 0):
        raise ProblemError(f"tolerance must be a positive length (model units), got {show(tolerance)}")
    if cells not in ("linear", "bezier"):
        raise ProblemError(f"cells must be 'linear' or 'bezier', got {show(cells)}")
    if not isinstance(compress, bool):
        raise ProblemError(f"compress must be True or False, got {show(compress)}")
    path = Path(path)
    if path.suffix.lower() != ".vtu":
        raise ProblemError(f"cannot write {path.name}: VTU files end in .vtu")
    check_folder(path, ProblemError)  # before sampling: fail fast on a bad output path
    sol = solution_or_model if isinstance(solution_or_model, (Solution, ElasticSolution)) else None
    model = sol.problem.model if sol is not None else as_model(solution_or_model)
    if cells == "bezier":
        grid = bezier_grid(sol, model)
    else:
        grid = sampled_grid(model, sol, samples, tolerance)
    return save_vtu(path, grid, compress)


def sampled_grid(model, solution=None, samples: int = 3, tolerance: float | None = None, patches=None):
    """The welded linear-hexahedron grid (a ``pyvista.UnstructuredGrid``) of a model or solution
    (:func:`iga.io.grids.sample_grid` with the solution's fields)."""
    if solution is None:
        return sample_grid(model, samples, tolerance, patches)
    fields = displacement_fields(solution) if isinstance(solution, ElasticSolution) else temperature_fields(solution)
    return sample_grid(model, samples, tolerance, patches, solution.problem, fields)


_XML_TYPES = {"f": "Float", "i": "Int", "u": "UInt", "b": "UInt"}


def write_pieces(path, solution, comm, samples: int = 3, tolerance: float | None = None) -> Path:
    """Under ``mpiexec``: every rank writes the patches it solved as ``STEM_RANK.vtu``, rank 0 the ``.pvtu`` that
    ParaView opens as one dataset; returns the ``.pvtu`` path (on every rank).

    ``solution`` comes from a distributed solve (its ``record.partition`` gives each patch's rank); the
    pieces are sampled on the whole model's conforming grids, so points on a rank boundary appear in both
    pieces at the same place (ParaView's Merge Blocks or Clean welds them into the serial file's points).
    Continuous fields (temperature, channels) are equal there; fields the serial file averages over the
    patches at a point (the heat flux, discontinuous across patches) are averaged by each piece over its
    own patches, so at a rank boundary the two pieces hold each side's value.

    Each piece is written by VTK's writer, atomically; the ``.pvtu`` (a short XML index of the pieces and
    their arrays) is written by rank 0 once every piece is in place: VTK's parallel writer lists the other
    ranks' pieces only when VTK itself is built with MPI, which pip's is not.  If any rank cannot write its
    piece, every rank removes its own, no index is written, and every rank raises :class:`ProblemError`.
    """
    import xml.etree.ElementTree as ET

    if not isinstance(solution, (Solution, ElasticSolution)):
        raise ProblemError(f"write_pieces writes a solution (iga.Solution or iga.ElasticSolution) of a distributed "
                           f"solve, got a {type(solution).__name__}; write a model with write_vtu")
    if not all(hasattr(comm, name) for name in ("Get_rank", "Get_size", "allreduce", "Barrier")):
        raise ProblemError(f"write_pieces needs the MPI communicator of the solve (e.g. mpi4py's MPI.COMM_WORLD), got "
                           f"{show(comm)}; write a serial solution with write_vtu")
    path = Path(path)
    if path.suffix.lower() != ".pvtu":
        raise ProblemError(f"cannot write {path.name}: parallel VTU files end in .pvtu")
    check_folder(path, ProblemError)
    part = solution.record.partition
    rank, size = comm.Get_rank(), comm.Get_size()
    if part is None or len(part) != len(solution.problem.model.patches) or part.max() >= size:
        raise ProblemError("write_pieces needs the solution of a distributed solve (solver='petsc' under mpiexec "
                           f"with {size} ranks); use write_vtu for a serial one")
    model = solution.problem.model
    piece = path.with_name(f"{path.stem}_{rank}.vtu")
    failure, grid = None, None
    try:  # sampling too: a rank that fails anywhere must still reach the collective below, or the others wait
        mine = np.flatnonzero(part == rank)
        if not len(mine):
            raise ProblemError(f"rank {rank} of {size} solved no patch ({len(part)} patches on {size} ranks): it has "
                               f"no piece to write; run with at most as many ranks as patches")
        grid = sampled_grid(model, solution, samples, tolerance, patches=mine)
        save_vtu(piece, grid)
    except ProblemError as err:
        failure = err
    written = comm.allreduce(0 if failure else 1)  # every rank's piece is in place before the index names it
    if written != size:
        piece.unlink(missing_ok=True)
        raise failure or ProblemError(f"{size - written} of {size} ranks could not write their pieces of "
                                      f"{path.name} (see their errors); no piece and no index is left")
    if rank == 0:
        root = ET.Element("VTKFile", type="PUnstructuredGrid", version="0.1", byte_order="LittleEndian",
                          header_type="UInt64")
        ugrid = ET.SubElement(root, "PUnstructuredGrid", GhostLevel="0")
        for tag, data in (("PPointData", grid.point_data), ("PCellData", grid.cell_data)):
            arrays = ET.SubElement(ugrid, tag)
            for name in data.keys():
                _array(arrays, name, np.asarray(data[name]))
        _array(ET.SubElement(ugrid, "PPoints"), "Points", np.asarray(grid.points))
        for r in range(size):
            ET.SubElement(ugrid, "Piece", Source=f"{path.stem}_{r}.vtu")
        atomic_write(path, lambda tmp: ET.ElementTree(root).write(tmp, xml_declaration=True, encoding="utf-8"),
                     ".pvtu", ProblemError)
    comm.Barrier()  # the index exists when any rank returns
    return path


def _array(parent, name: str, values: np.ndarray) -> None:
    """A ``PDataArray`` entry: VTK's XML type name (Float64, Int64, UInt8, ...) and the components."""
    import xml.etree.ElementTree as ET

    kind = _XML_TYPES[values.dtype.kind]
    attrs = {"type": f"{kind}{8 * values.dtype.itemsize}", "Name": name}
    if values.ndim > 1:
        attrs["NumberOfComponents"] = str(int(np.prod(values.shape[1:])))
    ET.SubElement(parent, "PDataArray", **attrs)
