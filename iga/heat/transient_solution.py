"""The result of a transient heat solve: the kept states in time, each a full :class:`iga.Solution`, probes as
time series, the stored heat, and a ParaView time series (``.pvd``).

A kept state is the temperature coefficients u and their rate du/dt (the scheme's own, so the discrete
equations hold exactly).  :meth:`TransientSolution.at` makes a :class:`TransientState`: a steady solution's
probes, heat flows per tag and energy figures, where the consistent boundary flow of a prescribed face is the
residual ``M du/dt + K u - f`` and the balance counts the heat stored, ``int rho c dT/dt dV`` (W).
"""

from __future__ import annotations

import shutil
from dataclasses import replace
import tempfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from geometry.errors import show
from geometry.io.files import atomic_write, check_folder
from geometry.numbers import TINY, is_integer, is_real

from solvers.info import SolveInfo

from iga.discretisation.locate import Locator
from iga.discretisation.problem import HeatBalance, SolveRecord
from iga.errors import ProblemError
from iga.discretisation.fields import evaluation_matrix
from iga.heat.solution import Solution

__all__ = ["TransientSolution", "TransientState"]

#: frames sampled together when a ParaView series is written (the geometry is sampled once per batch; the
#: sampled grid's size is checked against the memory budget by iga.io.grids.sample_grid)
_FRAMES_PER_PASS = 8


class TransientState(Solution):
    """The temperature of a transient solve at one ``time`` (s): a :class:`iga.Solution` whose balance
    includes the heat stored per second, ``stored_W`` = int rho c dT/dt dV (W; positive while warming)."""

    steady = False  # a state in time: no steady adjoint

    def __init__(self, problem, u, book, reaction_dofs, reaction, integrals, info, loads, prescribed, record,
                 time: float, stored_W: float):
        self.time, self.stored_W = float(time), float(stored_W)
        super().__init__(problem, u, book, reaction_dofs, reaction, integrals, info, loads=loads,
                         prescribed=prescribed, record=record)

    def __repr__(self) -> str:
        b = self.info["balance"]
        return (f"TransientState(t = {self.time:g} s, {self.info['patches']} patches, {self.info['dofs']} DOFs; "
                f"inflow {b['inflow_W']:.4g} W, stored {self.stored_W:.4g} W, balance error "
                f"{b['relative_error']:.1e})")

    def balance(self) -> HeatBalance:
        """Energy balance at this time (W): ``inflow_W`` (through faces, and a positive source) = ``outflow_W``
        (through faces, and a negative source) + ``stored_W`` (the heat stored per second), and the relative
        error of that identity (against the larger of the flows and the model's reference flow)."""
        b = super().balance()
        stored = self.stored_W
        scale = max(b.inflow_W, b.outflow_W, abs(stored), b.reference_flow_W, TINY)
        return replace(b, stored_W=stored, relative_error=abs(b.inflow_W - b.outflow_W - stored) / scale)


class TransientSolution:
    """Temperatures of a :class:`iga.heat.transient.TransientHeatProblem` at the kept times.

    Attributes
    ----------
    times : (n,) the kept times (s), the start and the end included
    record : :class:`iga.heat.stepping.StepRecord` (steps, rejections, prepared solvers, timings)
    """

    def __init__(self, stepper, kept):
        self._stepper = stepper
        self.problem = stepper.problem
        self.record = stepper.record
        self.times = np.array([k[0] for k in kept])
        self.times.setflags(write=False)
        self._U = np.stack([k[1] for k in kept])
        self._V = np.stack([k[2] for k in kept])
        self._locator = Locator(self.problem.model)

    def __len__(self) -> int:
        return len(self.times)

    def __repr__(self) -> str:
        r = self.record
        return (f"TransientSolution({r.method}, {r.steps} steps ({r.rejected} rejected) from {self.times[0]:g} to "
                f"{self.times[-1]:g} s, {len(self)} kept, {self.problem.ndof} DOFs, {r.prepared} prepared "
                f"{r.solver or 'solver'})")

    # ----------------------------------------------------------------- states
    def coefficients(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(u, du/dt) (ndof,) at time ``t`` (s): a kept state, or the linear interpolation of the two kept
        states around ``t``."""
        if not (is_real(t) and np.isfinite(t)):
            raise ProblemError(f"t must be a time in seconds, got {show(t)}")
        t0, t1 = float(self.times[0]), float(self.times[-1])
        margin = 1e-9 * (t1 - t0)
        if not (t0 - margin <= t <= t1 + margin):
            raise ProblemError(f"t = {t:g} s is outside the solved interval [{t0:g}, {t1:g}] s")
        i = int(np.argmin(np.abs(self.times - t)))
        if abs(self.times[i] - t) <= margin:
            return self._U[i], self._V[i]
        j = int(np.searchsorted(self.times, t))  # times[j - 1] < t < times[j]
        a = (t - self.times[j - 1]) / (self.times[j] - self.times[j - 1])
        return (1 - a) * self._U[j - 1] + a * self._U[j], (1 - a) * self._V[j - 1] + a * self._V[j]

    def at(self, t: float) -> TransientState:
        """The state at time ``t`` (s) as a :class:`TransientState` (a :class:`iga.Solution`: probes, flows
        per tag, balance with the stored heat, VTU export)."""
        u, v = self.coefficients(t)
        s = self._stepper
        reaction, prescribed, f, book = s.reaction(float(t), u, v)
        dd = s.dirichlet(book) if self.problem.changes_in_time else s.dirichlet_data
        Gd = dd.G[s.reaction_dofs].toarray() if dd.G is not None else np.zeros((len(s.reaction_dofs), 0))
        integrals = {key: Gd[:, j] for j, key in enumerate(dd.keys)}
        r = self.record
        info = SolveInfo(r.solver, r.iterations, 0.0, r.timings.get("setup", 0.0), r.timings.get("steps", 0.0),
                         {"time_scheme": r.method, "steps": r.steps, "rejected": r.rejected})
        Mv = s.M @ v
        record = SolveRecord(components=s.components, reduced_dofs=int(s.Pf.shape[1]),
                             constraint_stats=dict(s.constraints.stats) if s.constraints is not None else {},
                             timings={**self.problem.timings, **r.timings})
        loads = None if book["radiation"] else f - Mv  # (a radiating field has no linear energy identity)
        return TransientState(self.problem, u, book, s.reaction_dofs, reaction, integrals, info, loads,
                              prescribed, record, float(t), float(Mv.sum()))

    @property
    def final(self) -> TransientState:
        """The state at the end time."""
        return self.at(float(self.times[-1]))

    # ---------------------------------------------------------------- series
    def probe(self, points) -> np.ndarray:
        """Temperatures at physical points (N, 3) at every kept time: (n times, N)."""
        where, params = self._locator(np.asarray(points, float), 1e-10)
        return (evaluation_matrix(self.problem, where, params) @ self._U.T).T

    def heat_content(self) -> np.ndarray:
        """int rho c T dV (J, relative to T = 0) at every kept time: (n,)."""
        return self._U @ (self._stepper.M.T @ np.ones(self.problem.ndof))

    def stored_rate(self) -> np.ndarray:
        """int rho c dT/dt dV (W) at every kept time: (n,)."""
        return self._V @ (self._stepper.M.T @ np.ones(self.problem.ndof))

    # --------------------------------------------------------------- ParaView
    def write_pvd(self, path, every: int = 1, samples: int = 3, tolerance: float | None = None,
                  compress: bool = False) -> Path:
        """Write a ParaView time series: ``path`` (``.pvd``) and one ``.vtu`` per written time in the folder
        beside it named after its stem (``run.pvd`` and ``run/run_00000.vtu`` ...).  File > Open on the
        ``.pvd`` shows an animation of temperature (C) and heat flux (W/m^2) on the sampled grid of
        :func:`iga.write_vtu`.  ``every``: every ``every``-th kept time (the last always); ``samples``,
        ``tolerance``, ``compress``: as :func:`iga.write_vtu`.  Written to temporary names first: an existing series of
        the same name is replaced whole, and a failure leaves nothing half-written."""
        from iga.io.grids import sample_grid
        from iga.io.sampling import temperature_frames
        from iga.io.vtu import save_grid

        if not is_integer(every) or every < 1:
            raise ProblemError(f"every must be a positive integer, got {show(every)}")
        if not is_integer(samples) or samples < 1:
            raise ProblemError(f"samples must be a positive integer, got {show(samples)}")
        if not isinstance(compress, bool):
            raise ProblemError(f"compress must be True or False, got {show(compress)}")
        path = Path(path)
        if path.suffix.lower() != ".pvd":
            raise ProblemError(f"cannot write {path.name}: a ParaView time series ends in .pvd")
        folder = check_folder(path, ProblemError)
        frames = list(range(0, len(self.times), int(every)))
        if frames[-1] != len(self.times) - 1:
            frames.append(len(self.times) - 1)
        stem = path.stem
        target = folder / stem
        if target.exists() and not target.is_dir():
            raise ProblemError(f"cannot write the series' frames into {target}: a file of that name exists; "
                               "remove it or choose another name")
        tmp = Path(tempfile.mkdtemp(prefix=f".{stem}.", dir=folder))
        names = []
        try:
            for start in range(0, len(frames), _FRAMES_PER_PASS):
                batch = frames[start:start + _FRAMES_PER_PASS]
                suffixes = [f" {i}" for i in batch]
                grid = sample_grid(self.problem.model, samples, tolerance, None, self.problem,
                                   temperature_frames(self.problem, self._U[batch], suffixes))
                for i, suffix in zip(batch, suffixes):
                    frame = grid.copy(deep=False)
                    for other in suffixes:
                        for name in ("temperature", "heat_flux"):
                            frame.point_data.remove(name + other)
                    frame.point_data["temperature"] = grid.point_data["temperature" + suffix]
                    frame.point_data["heat_flux"] = grid.point_data["heat_flux" + suffix]
                    frame.field_data["TimeValue"] = np.array([self.times[i]])
                    name = f"{stem}_{i:05d}.vtu"
                    save_grid(frame, tmp / name, compress)
                    names.append((float(self.times[i]), f"{stem}/{name}"))
            old = None
            if target.exists():  # replaced whole: moved aside, then removed once the new one is in place
                old = Path(tempfile.mkdtemp(prefix=f".{stem}.old.", dir=folder))
                target.rename(old / stem)
            tmp.rename(target)
            tmp = None
            if old is not None:
                shutil.rmtree(old, ignore_errors=True)
        finally:
            if tmp is not None:
                shutil.rmtree(tmp, ignore_errors=True)
        lines = ['<?xml version="1.0"?>',
                 '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">', "  <Collection>"]
        lines += [f'    <DataSet timestep="{t!r}" group="" part="0" file={quoteattr(name)}/>' for t, name in names]
        lines += ["  </Collection>", "</VTKFile>", ""]
        return atomic_write(path, lambda p: Path(p).write_text("\n".join(lines)), ".pvd", ProblemError)
