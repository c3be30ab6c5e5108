"""The base trivariate of a two-to-one (bifurcation) bridge (Hong and Elber 2021, Section 3.5).

The base stands on the inlet face (its ``wmin`` face *is* that face).  Its two side faces are the bottom
face turned by ``alpha`` about its two opposite edges (those across the outlets' separation), scaled by
``height`` across the edge; its top joins the sides' top edges; its control net is the discrete Boolean sum
(Coons volume, on the Greville parameters) of these faces.  The arms (:func:`tiling.vrep.tubes.hermite_tube`)
join the side faces to the two outlets.
"""

from __future__ import annotations

import numpy as np

from geometry import BSpline
from geometry import knots as kn

from .tubes import Face, direction_field

__all__ = ["bifurcation_base"]


def bifurcation_base(inlet: Face, outlets: tuple, alpha: float = np.pi / 4, phi: float = 0.0,
                     height: float = 0.5):
    """The base trivariate of a two-to-one bridge on ``inlet`` towards the two ``outlets`` (Faces), Section 3.5.

    Returns (G, split, sides): the base geometry on [0, 1]^3 (its ``wmin`` face is the inlet face), the face
    direction it splits along (0: the outlets leave through ``umin``/``umax``; 1: ``vmin``/``vmax``), and the
    side face names in the order of ``outlets``.  ``alpha`` (radians, in (0, pi/2)): the angle between the
    bottom and each side face; the sides lean in, so their normals turn from the sides towards the outlets
    (pi/4: halfway).  ``height``: the sides are copies of the
    bottom scaled by it across their edge (1: the paper's full copies; shorter bases leave the arms more room).
    """
    F = inlet.surface
    d = direction_field(inlet, phi).points.reshape(-1, 3).mean(0)
    d /= np.linalg.norm(d)
    _, J = F.value_and_jacobian(np.array([[0.5, 0.5]]))
    rel = outlets[1].centre - outlets[0].centre
    rel -= np.dot(rel, d) * d
    axes = [J[0, :3, k] - np.dot(J[0, :3, k], d) * d for k in (0, 1)]
    split = int(np.argmax([abs(np.dot(rel, ax)) / np.linalg.norm(ax) for ax in axes]))
    net = F.control_points
    if split == 0:  # build along the second net axis, then transpose back
        net = np.swapaxes(net, 0, 1)
    nj = net.shape[1]
    Ut = F.knots[split]
    g = kn.greville(Ut, F.degrees[split])
    g = (g - g[0]) / (g[-1] - g[0])
    x = axes[1 - split] / np.linalg.norm(axes[1 - split])  # the rotation axis: along the edges kept
    sides = []
    for edge in (0, nj - 1):
        pivot = net[:, edge, :3]
        rows = net[:, ::1 if edge == 0 else -1, :3] - pivot[:, None]  # from the edge across the face
        R = _rotation_about(x, alpha, rows.reshape(-1, 3).mean(0), d)
        sides.append(pivot[:, None] + height * rows @ R.T)
    S0, S1 = sides  # (ni, nk, 3), k runs up the side from the bottom edge
    top = S0[:, -1][:, None] + g[None, :, None] * (S1[:, -1] - S0[:, -1])[:, None]
    B = net[..., :3]
    gj, gk = g[None, :, None, None], g[None, None, :, None]
    T = ((1 - gk) * B[:, :, None] + gk * top[:, :, None] + (1 - gj) * S0[:, None] + gj * S1[:, None]
         - ((1 - gj) * (1 - gk) * B[:, :1, None] + gj * (1 - gk) * B[:, -1:, None]
            + (1 - gj) * gk * top[:, :1, None] + gj * gk * top[:, -1:, None]))
    chan = np.broadcast_to(net[:, :, None, 3:], T.shape[:3] + (net.shape[-1] - 3,))
    T = np.concatenate([T, chan], axis=-1)
    degrees = [F.degrees[1 - split], F.degrees[split], F.degrees[split]]
    knots = [F.knots[1 - split], Ut, Ut]
    if split == 0:
        T = np.swapaxes(T, 0, 1)
        degrees[:2], knots[:2] = degrees[1::-1], knots[1::-1]
    G = BSpline(tuple(degrees), knots, T, channels=F.channels)
    names = ("umin", "umax") if split == 0 else ("vmin", "vmax")
    # which side faces which outlet
    c0 = G.boundary(names[0]).evaluate(np.array([[0.5, 0.5]]))[0, :3]
    c1 = G.boundary(names[1]).evaluate(np.array([[0.5, 0.5]]))[0, :3]
    first = np.linalg.norm(c0 - outlets[0].centre) + np.linalg.norm(c1 - outlets[1].centre)
    second = np.linalg.norm(c1 - outlets[0].centre) + np.linalg.norm(c0 - outlets[1].centre)
    return G, split, (names if first <= second else names[::-1])


def _rotation_about(axis, angle, v, up):
    """The rotation by ``angle`` about ``axis`` whose sense lifts ``v`` towards ``up``."""
    axis = axis / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    best = None
    for a in (angle, -angle):
        R = np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K
        lift = float(np.dot(R @ v, up))
        if best is None or lift > best[0]:
            best = (lift, R)
    return best[1]
