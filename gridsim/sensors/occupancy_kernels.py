"""Compiled footprint preparation for the occupancy grid: the same operations, in the same
order, as the NumPy code they replaced (``observe``'s range test and
:func:`~gridsim.vehicle.kinematics.box_corners`; the half-pixel inset and fixed-point
rounding before OpenCV's fill), and the world -> pixel map when it is diagonal (for other
maps the bits are BLAS's: NumPy's ``@`` stays)."""

from __future__ import annotations

import numpy as np

from gridsim.jit import fma32, kernel

# Corner signs along the length and the width (rear-right, front-right, front-left,
# rear-left), as in box_corners.
_LX = np.array([-1.0, 1.0, 1.0, -1.0])
_LY = np.array([-1.0, -1.0, 1.0, 1.0])


@kernel
def near_corners(active, x, y, psi, length, width, ex, ey, radius):
    """Corners ``(N, 4, 2)`` [m, world] of the active footprints (centres ``x, y``, headings
    ``psi`` [rad], sizes ``length x width`` [m]) whose bounding circle reaches within
    ``radius`` [m] of the ego ``(ex, ey)``, in fleet order."""
    idx = np.empty(len(x), np.int64)
    n = 0
    for i in range(len(x)):
        if active[i]:
            reach = radius + 0.5 * np.hypot(length[i], width[i])
            if np.hypot(x[i] - ex, y[i] - ey) <= reach:
                idx[n] = i
                n += 1
    out = np.empty((n, 4, 2))
    for m in range(n):
        i = idx[m]
        c, s = np.cos(psi[i]), np.sin(psi[i])
        hl, hw = 0.5 * length[i], 0.5 * width[i]
        for k in range(4):
            dx, dy = hl * _LX[k], hw * _LY[k]
            out[m, k, 0] = x[i] + c * dx - s * dy
            out[m, k, 1] = y[i] + s * dx + c * dy
    return out


@kernel
def pixel_quads(quads):
    """The rectangles ``quads`` ``(N, 4, 2)`` [pixels, corners ordered as box_corners] with
    each side moved half a pixel inwards, in OpenCV's 4-bit fixed point (int32, x 16)."""
    out = np.empty(quads.shape, np.int32)
    for m in range(quads.shape[0]):
        u = np.empty((2, 2))  # unit-ish side vectors scaled to the inset: length, width
        for side in range(2):
            corner = 1 if side == 0 else 3
            e0 = quads[m, corner, 0] - quads[m, 0, 0]
            e1 = quads[m, corner, 1] - quads[m, 0, 1]
            n = np.sqrt(e0 * e0 + e1 * e1)
            scale = np.minimum(0.5, 0.5 * n)
            u[side, 0] = e0 / np.maximum(n, 1e-9) * scale
            u[side, 1] = e1 / np.maximum(n, 1e-9) * scale
        for k in range(4):
            for j in range(2):
                p = quads[m, k, j] - _LX[k] * u[0, j] - _LY[k] * u[1, j]
                out[m, k, j] = np.int32(np.rint(p * 16))
    return out


@kernel
def diagonal_map(points, a):
    """``points @ a[:, :2].T + a[:, 2]`` for points ``(N, 2)`` and an affine map ``a``
    ``(2, 3)`` whose off-diagonal entries are zero: the same bits in any evaluation order."""
    out = np.empty(points.shape)
    for i in range(points.shape[0]):
        x, y = points[i, 0], points[i, 1]
        out[i, 0] = (x * a[0, 0] + y * a[0, 1]) + a[0, 2]
        out[i, 1] = (x * a[1, 0] + y * a[1, 1]) + a[1, 2]
    return out


@kernel
def pixel_points(points, a):
    """``np.rint(diagonal_map(points, a) * 16).astype(np.int32)``: polygon vertices ``(N, 2)``
    [m, world] in OpenCV's 4-bit fixed-point pixels, for a diagonal map ``a`` (one pass)."""
    px = diagonal_map(points, a)
    out = np.empty(points.shape, np.int32)
    for i in range(px.shape[0]):
        for j in range(2):
            out[i, j] = np.int32(np.rint(px[i, j] * 16))
    return out


@kernel
def box_quads(active, x, y, psi, length, width, ex, ey, radius, a):
    """``pixel_quads`` of the footprints of :func:`near_corners` mapped by the diagonal map
    ``a`` (:func:`diagonal_map`): the same kernels, in one call."""
    corners = near_corners(active, x, y, psi, length, width, ex, ey, radius)
    n = corners.shape[0]
    px = diagonal_map(corners.reshape((n * 4, 2)), a)
    return pixel_quads(px.reshape((n, 4, 2)))


@kernel
def block_sums(frames, p, out) -> None:
    """The sums of the ``p x p`` blocks of grids ``frames`` uint8 ``(N, H, W)`` into ``out``
    float32 ``(N, H / p, W / p)``, for pooling a grid: exact in any order (integers below
    2**24). Each block row's ``p`` grid rows are summed first, then each block's ``p``
    columns (``p = 2`` written out: six times faster)."""
    n, rows, cols = out.shape
    acc = np.empty(frames.shape[2], np.float32)
    for k in range(n):
        for i in range(rows):
            row = frames[k, i * p]
            for c in range(len(acc)):
                acc[c] = row[c]
            for a in range(1, p):
                row = frames[k, i * p + a]
                for c in range(len(acc)):
                    acc[c] += row[c]
            o = out[k, i]
            if p == 2:
                for j in range(cols):
                    o[j] = acc[2 * j] + acc[2 * j + 1]
                continue
            for j in range(cols):
                o[j] = acc[j * p]
            for b in range(1, p):
                for j in range(cols):
                    o[j] += acc[j * p + b]


@kernel
def pooled_convolution(frames, p, weight, bias, stride, pad, out) -> None:
    """A network's first convolution of grids and its ReLU, for ``K`` sets of weights on
    ``E`` grids each: grids ``frames`` uint8 ``(K, E, H, W)`` pooled in ``p x p`` blocks and
    scaled to 0-1 (:func:`block_sums`, then divided by ``p * p`` and by 255 in float32),
    zero-padded by ``pad`` cells, convolved at ``stride`` with ``weight[k]`` float32 ``(C, kh,
    kw)`` (one input channel) plus ``bias[k]`` ``(C,)``, into ``out`` float32 ``(E, K * C,
    OH, OW)`` (set ``k``'s channels of grid ``e`` at ``out[e, k * C:(k + 1) * C]``: the layout
    of a grouped convolution that follows).

    Each output sums its ``kh * kw`` products from zero in the taps' row-major order, each
    product fused with the sum (:func:`~gridsim.jit.fma32`), then adds the bias: the order in
    which torch's ``conv2d`` (oneDNN, im2col + BLAS) sums the rollouts' one-channel
    convolutions on the CPUs tried (AVX-512; not every shape: ``PopulationNet.convolutions``
    checks the bits per shape before using it). The input is split into ``stride x stride``
    phase planes, so that each tap is one contiguous pass."""
    n_k, n_e, rows, cols = frames.shape
    h, w = rows // p, cols // p
    n_c, kh, kw = weight.shape[1], weight.shape[2], weight.shape[3]
    oh, ow = out.shape[2], out.shape[3]
    # plane (pa, pb) holds the padded input's rows pa, pa + stride, ... and columns pb, pb +
    # stride, ...; a tap's pass runs over oh plane rows of wp cells (the last columns unused), and
    # may run past the last row's end by at most one row
    wp = (w + 2 * pad + stride - 1) // stride
    hp = max((h + 2 * pad + stride - 1) // stride, oh + (kh - 1) // stride + 1)
    planes = np.zeros((stride, stride, hp * wp), np.float32)
    acc = np.empty(oh * wp, np.float32)
    n = oh * wp
    # a block's value for each sum of its cells: (sum / (p * p)) / 255 in float32
    scaled = np.empty(p * p * 255 + 1, np.float32)
    for total in range(len(scaled)):
        scaled[total] = np.float32(total) / np.float32(p * p) / np.float32(255.0)
    sums = np.empty((n_e, h, w), np.float32)
    for k in range(n_k):
        block_sums(frames[k], p, sums)
        for e in range(n_e):
            for pa in range(stride):
                for pb in range(stride):
                    plane = planes[pa, pb]
                    for i in range(hp):
                        r = pa + i * stride - pad
                        if r < 0 or r >= h:
                            continue
                        row = sums[e, r]
                        for j in range(wp):
                            q = pb + j * stride - pad
                            if 0 <= q < w:
                                plane[i * wp + j] = scaled[int(row[q])]
            for c in range(n_c):
                acc[:] = 0.0
                for ky in range(kh):
                    for kx in range(kw):
                        wt = weight[k, c, ky, kx]
                        off = (ky // stride) * wp + kx // stride
                        src = planes[ky % stride, kx % stride, off : off + n]
                        for i in range(n):
                            acc[i] = fma32(wt, src[i], acc[i])
                b = bias[k, c]
                o = out[e, k * n_c + c]
                for oy in range(oh):
                    for ox in range(ow):
                        v = acc[oy * wp + ox] + b
                        o[oy, ox] = np.float32(0.0) if v <= 0.0 else v
