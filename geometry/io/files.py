"""Pickle-free save/load of splines (NumPy ``.npz``), exact round trip.

Format (version 1).  One ``.npz`` archive holding ``count`` splines; for the
``i``-th spline, keys prefixed ``s{i}_``:

    s{i}_degrees        int64 (d,)
    s{i}_knots{k}       float64 (n_k + p_k + 1,), k = 0..d-1
    s{i}_control_points float64 (n_1, ..., n_d, 3 + c)
    s{i}_weights        float64 (n_1, ..., n_d)   only for NURBS
    s{i}_channels       unicode (c,)

plus ``format`` = "iga-toolkit-splines" and ``version`` = 1.  Values are stored
as binary float64, so a round trip is bit-exact.  Loading uses
``allow_pickle=False``; writing goes to a temporary file renamed into place, so
an interrupted save never leaves a half-written file.
"""

from __future__ import annotations

import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np

from geometry.bspline import BSpline
from geometry.errors import SplineError
from geometry.resources import check_memory
from geometry.errors import show

FORMAT = "iga-toolkit-splines"
VERSION = 1

__all__ = ["save", "load", "save_all", "load_all", "atomic_write", "check_folder", "offscreen_plotter", "window_plotter",
           "save_screenshot"]


def check_folder(path, error=SplineError) -> Path:
    """The folder of ``path``; raises ``error`` if it is missing or not writable (call before long work)."""
    path = Path(path)
    if path.is_dir():
        raise error(f"cannot write {path}: it is a folder; give the name of a file inside it")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise error(f"cannot write {path}: folder {folder} does not exist; create it first")
    if not os.access(folder, os.W_OK):
        raise error(f"cannot write {path}: folder {folder} is not writable; choose another output folder")
    return folder


def atomic_write(path, write_fn, suffix: str = "", error=SplineError) -> Path:
    """Call ``write_fn(tmp_path)`` then rename the temporary file onto ``path``.

    The file gets the usual permissions (0666 masked by the umask; ``mkstemp``
    alone would leave 0600).  A missing or unwritable folder raises ``error``
    (the calling package's own exception type); on any failure the temporary
    file is removed, so nothing half-written is left behind.
    """
    path = Path(path)
    folder = check_folder(path, error)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=suffix, dir=folder)
    except OSError as exc:
        raise error(f"cannot write {path}: {exc.strerror}; choose a writable folder") from None
    os.close(fd)
    try:
        write_fn(tmp)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except OSError as exc:  # a full disk, a folder where the file should go, a lost permission
        _remove(tmp)
        why = "a folder of that name exists" if path.is_dir() else (exc.strerror or type(exc).__name__)
        raise error(f"cannot write {path}: {why}; nothing was written") from None
    except BaseException:
        _remove(tmp)
        raise
    return path


def _remove(tmp) -> None:
    if os.path.exists(tmp):
        os.unlink(tmp)


def save_all(path, splines) -> Path:
    """Save a list of :class:`BSpline` to ``path`` (``.npz``)."""
    splines = list(splines)
    arrays = {"format": np.array(FORMAT), "version": np.array(VERSION), "count": np.array(len(splines))}
    for i, s in enumerate(splines):
        if not isinstance(s, BSpline):
            raise SplineError(f"item {i} is a {type(s).__name__}, not a BSpline")
        arrays[f"s{i}_degrees"] = np.array(s.degrees, dtype=np.int64)
        for k, U in enumerate(s.knots):
            arrays[f"s{i}_knots{k}"] = np.asarray(U, float)
        arrays[f"s{i}_control_points"] = np.asarray(s.control_points, float)
        if s.is_rational:
            arrays[f"s{i}_weights"] = np.asarray(s.weights, float)
        arrays[f"s{i}_channels"] = np.array(s.channels, dtype=str).reshape(len(s.channels))

    def write(tmp):
        with open(tmp, "wb") as fh:
            np.savez(fh, **arrays)

    return atomic_write(path, write, suffix=".npz")


def save(path, spline: BSpline) -> Path:
    """Save one :class:`BSpline` to ``path`` (``.npz``)."""
    return save_all(path, [spline])


def _check_archive(path: Path) -> None:
    """Refuse archives that are not plain-array .npz files, before any array is allocated.

    Every member must be a ``.npy`` array without Python objects whose header
    claims no more bytes than the member holds (a 300-byte file cannot hold a
    745 GiB array); the total must fit the memory budget.
    """
    try:
        zf = zipfile.ZipFile(path)
    except (zipfile.BadZipFile, OSError):
        raise SplineError(f"{path} is not a spline file: it is not an .npz archive (write one with geometry.save)") from None
    total = 0
    with zf:
        for info in zf.infolist():
            if not info.filename.endswith(".npy"):
                raise SplineError(f"{path} holds {show(info.filename)}, which is not a NumPy array; not a spline file")
            try:
                with zf.open(info) as fh:
                    version = np.lib.format.read_magic(fh)
                    read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
                    shape, _, dtype = read(fh)
            except (ValueError, OSError, zipfile.BadZipFile, EOFError) as exc:
                raise SplineError(f"{path}: array {show(info.filename)} is damaged ({exc})") from None
            if dtype.hasobject:
                raise SplineError(f"{path}: array {show(info.filename)} holds Python objects; spline files hold numbers "
                                  "and text only, and objects are never unpickled")
            nbytes = int(np.prod(shape, dtype=np.float64)) * dtype.itemsize
            if nbytes > info.file_size:
                raise SplineError(f"{path}: array {show(info.filename)} claims {nbytes:.4g} bytes but the archive holds "
                                  f"{info.file_size} for it; the file is damaged or forged")
            total += nbytes
    check_memory(total, f"loading {path}")


def _integers(a: np.ndarray, path, name: str) -> np.ndarray:
    """An archive entry that must hold integers (stored as an integer type, not floats or strings)."""
    if a.dtype.kind not in "iu":
        raise SplineError(f"{path}: entry {name!r} holds {a.dtype} values {show(a.tolist())}, not integers; the "
                          "file is damaged or was not written by save_all")
    return a


def _reals(a: np.ndarray, path, name: str) -> np.ndarray:
    """An archive entry that must hold real numbers (stored as numbers, not strings)."""
    if a.dtype.kind not in "fiu":
        raise SplineError(f"{path}: entry {name!r} holds {a.dtype} values, not numbers; the file is damaged or was "
                          "not written by save_all")
    return a


def load_all(path) -> list[BSpline]:
    """Load every spline of a file written by :func:`save_all`."""
    path = Path(path)
    if path.is_dir():
        raise SplineError(f"{path} is a folder, not a spline file; give the path of an .npz file")
    if not path.is_file():
        raise SplineError(f"spline file {path} does not exist")
    _check_archive(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            if "format" not in data or str(data["format"]) != FORMAT:
                raise SplineError(f"{path} is not an iga-toolkit spline file (missing 'format' = {show(FORMAT)})")
            if int(data["version"]) != VERSION:
                raise SplineError(f"{path} has format version {int(data['version'])}; this build reads {VERSION}")
            count = _integers(data["count"], path, "count")
            if count.ndim or count < 1 or count > len(data.files):
                raise SplineError(f"{path}: entry 'count' is {show(count.tolist())}; a spline file holds at least one "
                                  f"spline and at most as many as its {len(data.files)} entries")
            out = []
            for i in range(int(count)):
                deg = tuple(int(p) for p in _integers(data[f"s{i}_degrees"], path, f"s{i}_degrees").ravel())
                knots = [_reals(data[f"s{i}_knots{k}"], path, f"s{i}_knots{k}") for k in range(len(deg))]
                w = _reals(data[f"s{i}_weights"], path, f"s{i}_weights") if f"s{i}_weights" in data else None
                cp = _reals(data[f"s{i}_control_points"], path, f"s{i}_control_points")
                try:
                    out.append(BSpline(deg, knots, cp, w, tuple(str(c) for c in data[f"s{i}_channels"])))
                except SplineError as exc:
                    raise SplineError(f"{path}: spline {i}: {exc}") from None
            return out
    except SplineError:
        raise
    except KeyError as exc:
        raise SplineError(f"{path} is incomplete: entry {exc} is missing; the file is damaged") from None
    except (zipfile.BadZipFile, OSError, ValueError, TypeError) as exc:
        raise SplineError(f"cannot read spline file {path}: {type(exc).__name__}; the file is damaged") from None


def load(path) -> BSpline:
    """Load the single spline of a file written by :func:`save`."""
    items = load_all(path)
    if len(items) != 1:
        raise SplineError(f"{path} holds {len(items)} splines; use load_all()")
    return items[0]


def offscreen_plotter(window=(1000, 800)):
    """A ``pyvista.Plotter`` that renders off screen (EGL works without X; VTK's note about it is silenced), lit
    from three sides so that no face of the model is left in shadow (colours read true on every side)."""
    import pyvista as pv

    pv.vtk_verbosity("off")
    return pv.Plotter(off_screen=True, window_size=list(window), lighting="three lights")


def window_plotter(window=(1000, 800)):
    """A ``pyvista.Plotter`` for a window on screen, lit as :func:`offscreen_plotter`'s (``pl.show()`` opens it)."""
    import pyvista as pv

    return pv.Plotter(window_size=list(window), lighting="three lights")


def save_screenshot(pl, path, error=SplineError, camera="iso", zoom: float = 1.0) -> Path:
    """Frame ``pl`` (``camera``, ``zoom``, white background), write it to the PNG ``path`` atomically, close it.

    ``error``: the calling package's exception for an unwritable path.
    """
    pl.camera_position = camera
    if zoom != 1.0:
        pl.camera.zoom(zoom)
    pl.set_background("white")
    try:
        return atomic_write(Path(path), lambda tmp: pl.screenshot(tmp), ".png", error)
    finally:
        pl.close()
