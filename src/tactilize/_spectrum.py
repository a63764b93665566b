"""Compiled passes of the feature analysis (numba), private to :mod:`tactilize.features`.

The analysis needs, beside one FFT, a window over the image and a handful of
power-weighted sums over the spectrum (total AC power, second moments, the
orientation tensor) and the strongest bin.  In NumPy those are a window pass
with a cached 2-D window and about six passes over the spectrum (|F|, its
square, three matrix-vector products against precomputed bases, an argmax),
which together cost half a bare FFT.  Here each is one pass that reads its
input once and keeps the small per-column tables in L1.

Imported on the first analysis, not by ``import tactilize``: numba takes a
few tenths of a second to import, and the compiled code is cached on disk
(``cache=True``) so only the first run on a machine compiles.

``fastmath`` allows reassociation only (so sums vectorise), never the
no-NaN/no-inf assumptions: a caller's NaN must stay a NaN.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_FASTMATH = {"reassoc", "contract", "arcp", "nsz"}


@njit(cache=True, fastmath=_FASTMATH, nogil=True)
def window_into(src, wy, wx, out):  # pragma: no cover - compiled; tested through its results
    """out[b, r, c] = src[b, r, c] * wy[r] * wx[c], as float32.

    ``src`` (B, H, W) of any real dtype and any strides; ``wy`` (H,) and
    ``wx`` (W,) float32 (``wx`` carries any scale such as 1/255); ``out``
    (B, H, W) float32.
    """
    nb, h, w = src.shape
    for i in range(nb):
        for r in range(h):
            f = wy[r]
            row = src[i, r]
            o = out[i, r]
            for c in range(w):
                o[c] = np.float32(row[c]) * (f * wx[c])


@njit(cache=True, fastmath=_FASTMATH, nogil=True)
def spectrum_sums(spec, w, ky_down, sums, peak_index):  # pragma: no cover - compiled; tested through its results
    """Power-weighted sums and the strongest bin of each half spectrum in a stack.

    Parameters
    ----------
    spec : float32 array (B, H, 2 * (W // 2 + 1))
        The rfft2 of each image viewed as interleaved (re, im) pairs.  The DC
        bin (0, 0) is left out of everything.
    w : int
        Width of the images [pixels] (fixes kx = column / w and the mirror weights).
    ky_down : float64 array (H,)
        Signed vertical frequency of each row [cycles/pixel], rows running down.
    sums : float64 array (B, 6), written
        Over the full spectrum (each stored column but the first and, for even
        W, the last counts twice for its mirror): sum P, sum P kx^2,
        sum P ky^2, sum P kx ky, sum P cos 2t, sum P sin 2t, with t the
        bin's angle (y down) and P = |F|^2.
    peak_index : int64 array (B,), written
        Flat index (row * (W // 2 + 1) + column) of the first bin holding the
        largest P, as ``argmax`` gives it.
    """
    nb, h, nc2 = spec.shape
    nc = nc2 // 2
    kx = np.empty(nc, np.float32)
    kx2 = np.empty(nc, np.float32)
    weight = np.empty(nc, np.float32)
    for c in range(nc):
        kx[c] = c / w
        kx2[c] = kx[c] * kx[c]
        weight[c] = 2.0
    weight[0] = 1.0
    if w % 2 == 0:
        weight[nc - 1] = 1.0
    power = np.empty(nc, np.float32)
    bits = power.view(np.int32)
    tiny = np.float32(1e-30)
    for i in range(nb):
        s0 = 0.0
        sxx = 0.0
        syy = 0.0
        sxy = 0.0
        sc = 0.0
        ss = 0.0
        best = np.int32(-1)
        best_index = 0
        for r in range(h):
            ky = np.float32(ky_down[r])
            ky2 = ky * ky
            row = spec[i, r]
            # Pass 1: the row's power.  Its maximum is taken over the float bits as
            # integers: for P >= 0 they order the same, and an integer max
            # vectorises where a float max (NaN rules) does not (4x faster here).
            for c in range(nc):
                re = row[2 * c]
                im = row[2 * c + 1]
                power[c] = re * re + im * im
            if r == 0:
                power[0] = 0.0
            row_max = np.int32(0)
            for c in range(nc):
                row_max = max(row_max, bits[c])
            # Pass 2: the sums, from the row still in L1.
            r0 = np.float32(0.0)
            r1 = np.float32(0.0)
            r2 = np.float32(0.0)
            rc = np.float32(0.0)
            rs = np.float32(0.0)
            for c in range(nc):
                q = weight[c] * power[c]
                k = kx[c]
                k2 = kx2[c]
                r0 += q
                r1 += q * k
                r2 += q * k2
                # At DC (the only bin with k = ky = 0) q is 0, so any finite 1/r^2 will do.
                q_r2 = q / max(k2 + ky2, tiny)
                rc += (k2 - ky2) * q_r2
                rs += k * q_r2
            s0 += r0
            sxx += r2
            syy += r0 * ky2
            sxy += r1 * ky
            sc += rc
            ss += 2.0 * ky * rs
            if row_max > best:
                best = row_max
                for c in range(nc):
                    if bits[c] == row_max:
                        best_index = r * nc + c
                        break
        sums[i, 0] = s0
        sums[i, 1] = sxx
        sums[i, 2] = syy
        sums[i, 3] = sxy
        sums[i, 4] = sc
        sums[i, 5] = ss
        peak_index[i] = best_index
