"""What the bridging of a V-model did, as typed counts (``VResult.bridges``)."""

from __future__ import annotations

from dataclasses import dataclass, field, fields

from .repulsion import Collisions

__all__ = ["SurfaceCounts", "UnionCounts", "BridgeReport"]


@dataclass
class SurfaceCounts:
    """One primitive's bridges to the trimming surface (Section 3.2): its anchoring faces, the bridges built,
    and those dropped because their target lies outside the primitive's domain."""

    anchoring_faces: int = 0
    built: int = 0
    dropped: int = 0


@dataclass
class UnionCounts:
    """What the bridging of one union did (Sections 3.4-3.6): union anchors of the lower-priority primitive,
    faces of the other on the shared surface, matches (one-to-one, two-to-one, unmatched faces), bridges
    given up because every shape tried folds (or the collision repulsion folded them), forks reduced to one tube (no room for a base), collision
    handling, the tubes and forks kept, and the anchors left open."""

    anchors: int = 0
    partner_faces: int = 0
    one_to_one: int = 0
    two_to_one: int = 0
    unmatched: int = 0
    folded: int = 0
    forks_reduced: int = 0
    collisions: Collisions = field(default_factory=Collisions)
    tubes: int = 0
    forks: int = 0
    open_anchors: int = 0


def _add(into, other) -> None:
    """Field-wise sum of two count dataclasses of one type (nested counts summed too)."""
    for f in fields(into):
        a, b = getattr(into, f.name), getattr(other, f.name)
        if isinstance(a, int):
            setattr(into, f.name, a + b)
        else:
            _add(a, b)


@dataclass
class BridgeReport:
    """Counts of a V-model's bridging: to the trimming surfaces (summed over the primitives; ``folded`` the
    surface bridges eliminated because every bend tried folds or leaves the map's domain, ``collisions``
    their collision handling, ``union_anchors_to_surface`` union anchors with nothing of the other primitive
    to meet, bridged to the surface instead), and of the unions (summed), with the patches they added."""

    surface: SurfaceCounts = field(default_factory=SurfaceCounts)
    folded: int = 0
    collisions: Collisions = field(default_factory=Collisions)
    union_anchors_to_surface: int = 0
    surface_bridges: int = 0
    union: UnionCounts = field(default_factory=UnionCounts)
    union_bridges: int = 0

    @property
    def bridges(self) -> int:
        """Bridging trivariates in the model: surface bridges kept and union bridge patches."""
        return self.surface_bridges + self.union_bridges

    def unbridged(self) -> dict:
        """Anchoring faces left without a bridge, by reason (only the reasons that occur): a surface bridge's
        target outside its map's domain, surface bridges given up as folded or eliminated by collisions, union
        anchors left open (unmatched, folded or eliminated)."""
        reasons = {"target outside the primitive's domain": self.surface.dropped,
                   "surface bridge folds with every bend tried": self.folded,
                   "surface bridge eliminated by a collision": self.collisions.eliminated,
                   "union anchor left open (unmatched, folded or eliminated)": self.union.open_anchors}
        return {k: int(v) for k, v in reasons.items() if v}

    def as_dict(self) -> dict:
        """The counts for a summary: anchoring faces, bridges, and the faces left without one by reason."""
        return {"anchoring_faces": self.surface.anchoring_faces + self.union.anchors,
                "surface_bridges": self.surface_bridges, "union_bridges": self.union_bridges,
                "unbridged": self.unbridged()}

    def add_surface(self, counts: SurfaceCounts) -> None:
        _add(self.surface, counts)

    def add_union(self, counts: UnionCounts, patches: int) -> None:
        _add(self.union, counts)
        self.union_bridges += patches
