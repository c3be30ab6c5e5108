"""The hp choice per patch (Melenk and Wohlmuth 2001, Section 4): split a marked patch where its indicator
exceeds the one predicted for it, raise its degree where it does not.

After a patch is split, its children's error is predicted to fall as h^p would make it (by gamma_h 2^(-2 p) of
the parent's squared indicator, shared by the 8 children); after its degree is raised, by gamma_p; a patch left as
it is keeps gamma_n times its prediction.  A patch whose indicator then exceeds its prediction is not smooth
enough for its degree to pay (a singularity): it is split; one whose error fell as predicted is smooth there: its
degree is raised.  Patches without a prediction (the start) are split.  The constants are Melenk and Wohlmuth's
(gamma_h = 4, gamma_p = 0.4, gamma_n = 1).
"""

from __future__ import annotations

import numpy as np

__all__ = ["GAMMA_H", "GAMMA_P", "GAMMA_N", "choose", "refine_hp", "predictions"]

GAMMA_H, GAMMA_P, GAMMA_N = 4.0, 0.4, 1.0


def _keys(leaves) -> list:
    """A leaf's identity, kept while it is not split: (root, depth, position)."""
    return [(int(r), int(d), *map(int, i)) for r, d, i in zip(leaves.root, leaves.depth, leaves.index)]


def choose(tree, eta2: np.ndarray, marked: np.ndarray, predicted: dict):
    """(split, raise): the marked leaves whose squared indicator ``eta2`` exceeds their prediction (or have none)
    and the others."""
    keys = _keys(tree.leaves)
    over = np.array([eta2[i] > predicted.get(keys[i], 0.0) for i in marked], bool)
    return marked[over], marked[~over]


def refine_hp(tree, split, raise_, analysis_refine: int = 0):
    """The tree with the leaves ``split`` refined by h (:meth:`TileRefinement.refined`) and the leaves ``raise_``
    by p (found again by their identity after the split's closure; one that the closure split is left)."""
    keys = _keys(tree.leaves)
    wanted = {keys[i] for i in raise_}
    out = tree.refined(split, "h", analysis_refine) if len(split) else tree
    if wanted:
        now = _keys(out.leaves)
        idx = np.array([j for j, k in enumerate(now) if k in wanted], np.int64)
        if len(idx):
            out = out.refined(idx, "p", analysis_refine)
    return out


def predictions(tree, new, eta2: np.ndarray, split, raise_, predicted: dict) -> dict:
    """The predicted squared indicators of the leaves of ``new`` after ``tree`` was refined (module notes)."""
    keys = _keys(tree.leaves)
    degree = [int(max(tree.roots.patches[r].spline.degrees)) + int(e)
              for r, e in zip(tree.leaves.root, tree.leaves.elevation)]
    out: dict = {}
    for i in split:
        share = GAMMA_H * 0.5 ** (2 * degree[i]) * eta2[i]
        r, d, *ix = keys[i]
        out[keys[i]] = share  # bisected in place (a patch with slots): the same leaf
        for o in range(8):
            child = (r, d + 1, *(2 * v + ((o >> (2 - k)) & 1) for k, v in enumerate(ix)))
            out[child] = share / 8
    for i in raise_:
        out[keys[i]] = GAMMA_P * eta2[i]
    for key, value in predicted.items():
        out.setdefault(key, GAMMA_N * value)
    present = set(_keys(new.leaves))
    return {k: v for k, v in out.items() if k in present}
