"""Random implicit micro-structures with guaranteed connectivity (Massarwi et al. 2018, Section 4).

The parameter domain of a deformation map D is split into a grid of cells;
each cell carries a scalar trivariate B-spline f (degree d, ``controls``
coefficients per direction) on its box, and the structure is the region
f > 0, its surface the zero set f = 0 mapped through D.  Coefficients are
p = (1 - alpha) p0 + alpha U(-1, 1) (Eq. 6) around a canonical tile's p0.

All cells together form one global B-spline F over D's domain: neighbouring
cells share their boundary layer of coefficients, which is C0 (Eq. 7; knots
of multiplicity d at cell boundaries), and with ``continuity="C1"`` the first
inner layers on both sides are placed symmetrically about it (Eq. 8).  The
connectivity steps (:mod:`tiling.implicit.connect`) then work on that one
coefficient array, repeated until none has work left:

* inter-cell (Section 4.2.1): ``connectivity`` edge-disjoint spanning trees
  of the cells' face-adjacency graph (scipy.sparse.csgraph); every tree face
  is anchored by a negative sample and raised (even iterations: one more
  coefficient positive; odd: all raised) until it changes sign on its samples;
* intra-cell (Section 4.2.2): the sampled inside region of every cell is made
  one connected component (scipy.ndimage.label) by raising the coefficients
  along least-cost bridges between its components;
* cavities (unless shelled): negative pockets enclosed by the inside region,
  which would be extra surface components (and trap powder in a printed
  part), are tunnelled to the outside;
* capping (Section 6.2, item 2): D's boundary layers of coefficients are set
  to -1 and held, so the zero set stays inside, at least Lemma 1's distance
  from the boundary (:meth:`ImplicitStructure.cap_distance`); shelling: the
  coefficients within ``shell`` of the boundary are set positive and the
  surface is closed by D's boundary where f > 0.

These steps work on the samples of the build ``resolution``.  Once they
hold, the certificate of :mod:`tiling.implicit.certify` checks the spline
itself (Bernstein bounds of sub-boxes at least as fine as the samples): the
inside and the outside (or a shell's voids) are each connected, every tree
face has a pair of positive boxes across it, and no critical value of F lies
within a margin of zero, so no neck, island or pocket hides between samples;
where it fails, coefficients are raised or lowered as the steps do, and all
steps run again.  ``stats["certificate"]`` says whether it holds
(``certified``) and what it changed.  A face or cell that already satisfies
its condition is left unchanged, so ``alpha = 0`` with a connected canonical
tile reproduces the canonical tiling.
Randomness comes from ``numpy.random.default_rng(seed)`` only.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from geometry import BSpline, SplineFunction
from geometry import knots as kn
from geometry.errors import check_seed, show
from geometry.resources import check_memory

from tiling.errors import TilingError
from tiling.checks import check_counts, check_map
from tiling.implicit.surface import EdgeSplines, SurfaceOutputs, zero_surface
from tiling.implicit.connect import (Builder, cell_knots, connect_cells, connect_faces, grid_graph, open_cavities,
                               spanning_trees)
from tiling.implicit.boxes import box_grid
from tiling.implicit.certify import Certifier
from geometry.tolerances import SAME_KNOT
from geometry.numbers import is_flag, is_integer, is_real

__all__ = ["random_implicit", "ImplicitStructure", "canonical_tubes"]

_CAP = -1.0  # coefficient of D's boundary layers when capping (Lemma 1's p_0)


def canonical_tubes(degree: int = 3, controls: int = 8, radius: float = 0.3) -> np.ndarray:
    """The default canonical tile's coefficients (controls,) * 3: three tubes through the cell's centre.

    p0 = (radius - distance to the nearest of the three axes through the
    centre) / radius at the Greville points, clipped to [-1, 1]: positive
    inside tubes along x, y and z that meet the six faces in discs, so copies
    connect to their neighbours.
    """
    g = kn.greville(kn.uniform_knots(degree, controls - degree), degree)
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    d = np.minimum(np.minimum(np.hypot(y - 0.5, z - 0.5), np.hypot(x - 0.5, z - 0.5)), np.hypot(x - 0.5, y - 0.5))
    return np.clip((radius - d) / radius, -1.0, 1.0)


def _global_knots(lo, hi, cells, degree, controls):
    """Knots over [lo, hi] of ``cells`` cells glued C0: multiplicity ``degree`` at the cell boundaries."""
    inner = cell_knots(degree, controls)
    h = (hi - lo) / cells
    parts = [np.full(degree + 1, lo)]
    for c in range(cells):
        parts.append(lo + h * (c + inner))
        parts.append(np.full(degree if c < cells - 1 else degree + 1, lo + h * (c + 1)))
    return np.concatenate(parts)


@dataclass
class ImplicitStructure(SurfaceOutputs):
    """A random implicit micro-structure: the global field F (f > 0 inside) over D's domain, and its statistics.

    ``field``: scalar :class:`geometry.SplineFunction` on D's parameter domain;
    ``counts``: cells per direction; ``trees``: the spanning trees' edges, each
    (E, 2) cell indices; ``stats``: iteration counts per face and per cell,
    trees found, cavities filled; ``materials``: the material channels (one
    component each, named ``material_names``) on the same space as ``field``.
    """

    outer: BSpline
    counts: tuple
    degree: int
    controls: int
    continuity: str
    field: SplineFunction
    trees: list
    stats: dict = field(default_factory=dict)
    cap: bool = False
    shell: float | None = None
    resolution: int = 12
    materials: SplineFunction | None = None
    material_names: tuple = ()

    def cell_box(self, cell) -> np.ndarray:
        """Parameter box (3, 2) of cell (q, r, s) in D's domain."""
        dom = self.outer.domain
        h = (dom[:, 1] - dom[:, 0]) / np.asarray(self.counts)
        lo = dom[:, 0] + h * np.asarray(cell)
        return np.stack([lo, lo + h], axis=1)

    def cell_coefficients(self, cell) -> np.ndarray:
        """The (controls,) * 3 coefficients of cell (q, r, s) (a view into the global array)."""
        n = self.controls - 1
        G = self.field.coefficients[..., 0]
        return G[tuple(slice(c * n, c * n + self.controls) for c in cell)]

    def cell_field(self, cell) -> SplineFunction:
        """Cell (q, r, s)'s own scalar trivariate f^{qrs} on its parameter box (Eq. 5), built from its coefficients."""
        box = self.cell_box(cell)
        inner = cell_knots(self.degree, self.controls)
        knots = [np.concatenate([np.full(self.degree + 1, lo), lo + (hi - lo) * inner, np.full(self.degree + 1, hi)])
                 for lo, hi in box]
        return SplineFunction((self.degree,) * 3, knots, self.cell_coefficients(cell)[..., None].copy())

    def cap_distance(self) -> np.ndarray:
        """Lemma 1's lower bound (3,) on the parameter distance of the zero set from D's boundary (capped only).

        On a line normal to a boundary face, f is a univariate B-spline whose
        first coefficient is at most p_0 = -1 and the others at most M (the
        largest coefficient); on the first knot span its Bezier form has
        p_0 first and coefficients <= M after, so (Massarwi et al. 2018,
        Lemma 1, with M for 1) a zero at local t satisfies
        t >= 1 - (M / (M - p_0))^(1/d).  Times the span's length per direction.
        """
        if not self.cap:
            raise TilingError("cap_distance applies to a capped structure; build it with cap=True")
        M = max(float(self.field.coefficients.max()), 0.0)
        t = 1.0 - (M / (M - _CAP)) ** (1.0 / self.degree) if M > 0 else 1.0
        span = (self.outer.domain[:, 1] - self.outer.domain[:, 0]) / np.asarray(self.counts) / (
            self.controls - self.degree)
        return t * span

    def sample(self, resolution: int | None = None) -> tuple[list, np.ndarray]:
        """Parameter axes and F on the global grid with ``resolution`` intervals per cell and direction."""
        resolution = self.resolution if resolution is None else resolution
        if not is_integer(resolution) or resolution < 1:
            raise TilingError(f"resolution must be a positive integer (samples per cell and direction), got "
                              f"{show(resolution)}")
        n = float(np.prod([c * resolution + 1.0 for c in self.counts]))
        # the grid values, VTK's copy of them, the contour's masks and edge tables: about 6 doubles per point
        check_memory(n * 8 * 6, f"sampling the field at resolution {resolution} ({n:.3g} grid points)", TilingError,
                     "lower the resolution")
        dom = self.outer.domain
        axes = [np.linspace(dom[k, 0], dom[k, 1], self.counts[k] * resolution + 1) for k in range(3)]
        return axes, self.field.evaluate_grid(axes)[..., 0]

    def sample_values(self, resolution: int | None = None) -> np.ndarray:
        """F on the global grid (:meth:`sample`) without the axes."""
        return self.sample(resolution)[1]

    def surface(self, resolution: int | None = None, close: bool | None = None, snap: bool = True):
        """The zero set mapped exactly through D, one welded ``pyvista.PolyData`` (:mod:`tiling.implicit.surface`).

        The field is sampled on the global grid (``resolution`` intervals per
        cell and direction), contoured at 0 in parameter space (VTK flying
        edges), every vertex moved along its grid edge onto the exact zero set
        of the spline (``snap``: |f| < 1e-12 max|p|) and mapped through D, so
        shared cell faces carry identical vertices and the mesh is one piece.
        The connectivity (one component, closed when capped) is certified on
        the spline itself (``stats["certificate"]``), which rules out necks,
        islands and pockets near critical values; a sheet thinner than the
        sampling step can still split off a small piece (where an uncapped
        zero set grazes D's boundary), and a sampling coarser than the build
        ``resolution`` (the default here) may miss thin parts.  ``close``
        (default: when shelled) closes the surface with D's boundary where
        f > 0.  Point data: every channel
        of D and every material channel at the vertices, and the parameters
        (u, v, w).
        """
        axes, F = self.sample(resolution)
        close = self.shell is not None if close is None else bool(close)

        def materials(params):
            if self.materials is None:
                return {}
            values = self.materials.evaluate(params, compiled=False)
            return {c: values[:, i] for i, c in enumerate(self.material_names)}

        return zero_surface(axes, F, self.outer, lambda x: self.field.evaluate(x, compiled=False)[:, 0],
                            close=close, snap_vertices=snap, scale=float(np.abs(self.field.coefficients).max()),
                            point_data=materials, stats=self.stats,
                            lines=lambda a, b, axis: EdgeSplines.of(self.field, a, b, axis))


# ----------------------------------------------------------------------------------------------- building
def _check_inputs(D, counts, degree, controls, alpha, continuity, connectivity, canonical, shell):
    check_map(D)  # the check every builder shares: a trivariate, not folded
    check_counts(counts, 3, "counts (cells per direction)")
    for name, v, lo in (("degree", degree, 1), ("controls", controls, 2)):
        if not is_integer(v) or v < lo:
            raise TilingError(f"{name} must be an integer >= {lo}, got {show(v)}")
    if controls < degree + 1:
        raise TilingError(f"controls must be at least degree + 1 = {degree + 1} coefficients per direction, "
                          f"got {controls}")
    if not (is_real(alpha) and 0 <= alpha <= 1):
        raise TilingError(f"alpha must be a number in [0, 1] (the randomization factor of Eq. 6), got {show(alpha)}")
    if continuity not in ("C0", "C1"):
        raise TilingError(f"continuity must be 'C0' or 'C1', got {show(continuity)}")
    if continuity == "C1" and controls < 4:
        raise TilingError(f"C1 continuity needs at least 4 coefficients per direction, got controls={controls}")
    if not is_integer(connectivity) or not 1 <= connectivity <= 3:
        raise TilingError(f"connectivity must be 1, 2 or 3 (edge-disjoint spanning trees), got {show(connectivity)}")
    if shell is not None and not (is_real(shell) and 0 < shell < 0.5):
        raise TilingError(f"shell must be a thickness in (0, 0.5) of a boundary cell (its parameter fraction), "
                          f"got {show(shell)}")
    shape = (controls,) * 3
    if canonical is None:
        return canonical_tubes(degree, controls)
    p0 = canonical.coefficients[..., 0] if isinstance(canonical, SplineFunction) else np.asarray(canonical, float)
    if isinstance(canonical, SplineFunction) and (canonical.n_components != 1 or canonical.dim != 3
                                                  or tuple(canonical.degrees) != (degree,) * 3):
        raise TilingError(f"the canonical tile must be a scalar trivariate of degree {degree} in every direction, "
                          f"got {canonical!r}")
    if isinstance(canonical, SplineFunction):
        want = cell_knots(degree, controls)
        for U in canonical.knots:
            inner = (U[degree + 1:-degree - 1] - U[0]) / (U[-1] - U[0])
            if inner.shape != want.shape or not np.allclose(inner, want, atol=SAME_KNOT):
                raise TilingError(f"the canonical tile's knots must be uniform ({controls - degree} spans per "
                                  f"direction, as every cell's), got interior knots {show(inner)} (scaled to [0, 1]); "
                                  f"pass its coefficients instead to reinterpret them on uniform knots")
    if p0.shape != shape or not np.all(np.isfinite(p0)):
        raise TilingError(f"the canonical tile must have {shape} finite coefficients (degree {degree}, "
                          f"controls {controls}), got shape {p0.shape}")
    return p0


def random_implicit(D: BSpline, counts, *, degree: int = 3, controls: int = 8, alpha: float = 0.5, seed: int = 0,
                    continuity: str = "C0", connectivity: int = 1, canonical=None, cap: bool = False,
                    shell: float | None = None, resolution: int = 12, materials: dict | None = None
                    ) -> ImplicitStructure:
    """Random implicit micro-structure in D (Massarwi et al. 2018, Section 4; module notes).

    Parameters
    ----------
    D : trivariate deformation map; its parameter domain is split into ``counts`` = (cx, cy, cz) cells
    degree, controls : degree and coefficients per direction of each cell's field
    alpha : randomization factor in [0, 1] (Eq. 6); 0 gives the canonical tiling
    seed : seed of the random generator (same seed, same structure)
    continuity : "C0" (shared boundary coefficients, Eq. 7) or "C1" (and Eq. 8)
    connectivity : edge-disjoint spanning trees along which neighbouring cells are connected (1 to 3)
    canonical : the canonical tile, a scalar trivariate of the cells' space or its (controls,) * 3
        coefficients; default :func:`canonical_tubes`
    cap : close the structure inside D (negative coefficients on D's boundary)
    shell : thickness (fraction of a boundary cell) of a solid layer along D's boundary
    resolution : samples per cell and direction of the connectivity checks (and the surface's default)
    materials : {name: (controls,) * 3 coefficients of one cell} material channels, tiled into every cell
        like the canonical tile (not randomized; shared layers take one cell's values, so C0); the surface
        carries them as point data

    >>> from geometry import primitives
    >>> s = random_implicit(primitives.box(), (2, 2, 2), alpha=0.6, seed=1, cap=True)
    >>> s.stats["trees"], s.surface().n_cells > 1000
    (1, True)
    """
    p0 = _check_inputs(D, counts, degree, controls, alpha, continuity, connectivity, canonical, shell)
    if cap and shell is not None:
        raise TilingError("cap=True and shell are exclusive: a capped structure closes D's boundary with walls, a "
                          "shelled one with a shell of the given thickness; choose one")
    check_seed(seed, TilingError)
    if not is_flag(cap):
        raise TilingError(f"cap must be true or false, got {show(cap)}")
    if not is_integer(resolution) or resolution < 2:
        raise TilingError(f"resolution must be an integer >= 2 (samples per cell and direction), got {show(resolution)}")
    counts = tuple(int(c) for c in counts)
    n_cells = int(np.prod(counts))
    per_span = -(-resolution // (controls - degree))  # the certificate's sub-boxes: at least as fine as the samples
    # samples and coefficients in a few copies; per certificate box its bounds, bits, labels and graph edges
    check_memory(n_cells * ((controls ** 3 + (resolution + 1) ** 3) * 8 * 4 + (per_span * (controls - degree)) ** 3
                            * 160), f"the random implicit structure ({n_cells} cells)", TilingError,
                 "lower the counts or the resolution")
    rng = np.random.default_rng(seed)
    B = Builder(counts, degree, controls, continuity)
    cells = np.stack(np.unravel_index(np.arange(n_cells), counts), 1)
    for c in cells:  # Eq. 6 per cell; shared boundary layers take the value of the last cell written (C0, Eq. 7)
        B.G[B.cell_slices(c)] = (1 - alpha) * p0 + alpha * rng.uniform(-1.0, 1.0, p0.shape)
    B.enforce_c1()
    edges = grid_graph(counts)
    trees = spanning_trees(n_cells, edges, connectivity, rng)
    stats = {"trees": len(trees), "face_iterations": {}, "cell_iterations": {}, "cavities_opened": 0}
    _boundary_layers(B, cap, shell)
    tree_edges = np.concatenate(trees) if trees else np.zeros((0, 2), np.int64)
    knots = [_global_knots(*D.domain[k], counts[k], degree, controls) for k in range(3)]
    out = ImplicitStructure(D, counts, degree, controls, continuity, None, trees, stats, bool(cap), shell,
                            int(resolution), *_materials(materials, B, cells, knots, D))
    # The steps interact (C1 symmetry moves lines of a face, filling a pocket may start an island, a cell's
    # steps may fill a face): repeat them all until one round changes nothing.
    # The certificate on the spline (tiling.implicit.certify) runs once the sampled steps hold.
    certifier = Certifier(box_grid([_global_knots(0.0, c, c, degree, controls) for c in counts], degree, counts,
                                   per_span), B.G.shape)
    for _ in range(100):
        work = connect_faces(B, cells, tree_edges, resolution, stats)
        work += connect_cells(B, cells, resolution, stats)
        out.field = SplineFunction((degree,) * 3, knots, B.G[..., None])
        if shell is None:  # (a shell encloses every void by design)
            work += open_cavities(out.sample_values, B, resolution, stats)
        if not work:
            work = certifier.round(B, cells, tree_edges, shell, stats)
            B.enforce_c1()
            out.field = SplineFunction((degree,) * 3, knots, B.G[..., None])
        if not work:
            break
    else:
        raise TilingError("the connectivity steps did not settle in 100 rounds; lower alpha or use C0 continuity")
    stats["rounds"] = _ + 1
    return out


def _boundary_layers(B, cap, shell):
    """Capping (D's boundary layers of coefficients at -1, held fixed) or shelling (layers within ``shell`` of a
    boundary cell raised to at least 1)."""
    if not cap and shell is None:
        return
    for k in range(3):
        G = np.moveaxis(B.G, k, 0)
        if shell is not None:
            layers = max(1, int(np.ceil(shell * (B.N - 1))))
            G[:layers] = np.maximum(G[:layers], 1.0)
            G[-layers:] = np.maximum(G[-layers:], 1.0)
        else:
            G[0] = G[-1] = _CAP
            np.moveaxis(B.fixed, k, 0)[[0, -1]] = True


def _materials(materials, B, cells, knots, D):
    """The material channels as one SplineFunction over the cells' space, and their names."""
    if materials is None or len(materials) == 0:
        return None, ()
    if not isinstance(materials, dict):
        raise TilingError(f"materials must be a dict {{name: coefficients}}, got {type(materials).__name__}")
    shape = (B.N,) * 3
    names, coefs = [], []
    for name, c in materials.items():
        a = np.asarray(c, dtype=float) if isinstance(c, (list, tuple, np.ndarray)) else None
        if not isinstance(name, str) or not name or a is None or a.shape != shape or not np.all(np.isfinite(a)):
            raise TilingError(f"material {name!r} must be named by a non-empty string and have {shape} finite "
                              f"coefficients (one cell's, degree {B.d}, controls {B.N}), got "
                              f"{type(c).__name__} of shape {np.shape(c)}")
        if name in D.channels or name in ("u", "v", "w"):
            raise TilingError(f"material {name!r} clashes with a channel of the map or a parameter name; rename it")
        G = np.zeros(B.G.shape)
        for cell in cells:
            G[B.cell_slices(cell)] = a
        names.append(name)
        coefs.append(G)
    return SplineFunction((B.d,) * 3, knots, np.stack(coefs, axis=-1)), tuple(names)


