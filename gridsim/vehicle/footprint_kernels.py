"""Compiled tests on vehicle footprints: oriented boxes ``(x, y, psi, length, width)``
(centre [m], heading [rad], size [m]), shared by the traffic's crossing rule and the world's
collision broad phase."""

from __future__ import annotations

import numpy as np

from gridsim.jit import kernel


@kernel
def boxes_apart(a, b, margin) -> bool:
    """Whether two oriented boxes ``(x, y, psi, length, width)`` [m, rad] (centre, heading,
    size) are apart by more than ``margin`` [m] along one of their four edge normals
    (separating axes). Then they cannot touch whatever pymunk's rounding; otherwise they may."""
    ax, ay, apsi, alen, awid = a
    bx, by, bpsi, blen, bwid = b
    box_a = (ax, ay, np.cos(apsi), np.sin(apsi), alen, awid)
    return oriented_boxes_apart(box_a, (bx, by, np.cos(bpsi), np.sin(bpsi), blen, bwid), margin)


@kernel
def oriented_boxes_apart(a, b, margin) -> bool:
    """:func:`boxes_apart` of boxes given as ``(x, y, cos psi, sin psi, length, width)``."""
    ax, ay, ac, as_, alen, awid = a
    bx, by, bc, bs, blen, bwid = b
    dx, dy = bx - ax, by - ay
    for k in range(4):
        if k == 0:
            ux, uy = ac, as_
        elif k == 1:
            ux, uy = -as_, ac
        elif k == 2:
            ux, uy = bc, bs
        else:
            ux, uy = -bs, bc
        reach_a = 0.5 * (alen * abs(ac * ux + as_ * uy) + awid * abs(-as_ * ux + ac * uy))
        reach_b = 0.5 * (blen * abs(bc * ux + bs * uy) + bwid * abs(-bs * ux + bc * uy))
        if abs(dx * ux + dy * uy) - reach_a - reach_b > margin:
            return True
    return False
