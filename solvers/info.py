"""What a solve reports: :class:`SolveInfo`."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["SolveInfo"]


@dataclass
class SolveInfo:
    """Diagnostics of one solve.

    method : backend name actually used
    iterations : Krylov iterations (0 for direct)
    residual : final relative residual ||b - A x|| / ||b||
    setup_s, solve_s : seconds spent in factorisation/hierarchy set-up and in the solve
    extra : backend-specific details (e.g. AMG levels and operator complexity)
    """

    method: str
    iterations: int
    residual: float
    setup_s: float
    solve_s: float
    extra: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """The diagnostics as a plain dictionary (for JSON summaries)."""
        return {"method": self.method, "iterations": self.iterations, "residual": self.residual,
                "setup_s": self.setup_s, "solve_s": self.solve_s, **self.extra}
