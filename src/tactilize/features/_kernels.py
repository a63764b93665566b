"""The two compiled passes of the feature analysis (numba).

Beside one FFT the analysis reads every pixel once (the window) and every
spectrum bin once (power-weighted sums and the strongest bin).  Written in
NumPy these are a window pass through a cached 2-D window and about six passes
over the spectrum (|F|, its square, three products against frequency tables,
an argmax), which together cost half a bare FFT.  Compiled, each is a single
pass that reads its input once and keeps the small per-column tables in L1.

Nothing else is compiled: each kernel fills documented arrays, one row per
image, and :mod:`tactilize.features._analysis` turns them into the features
in NumPy, like scikit-image's ``_glcm_loop`` fills the co-occurrence matrix
that ``graycoprops`` interprets.

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
def window_into(src, wy, wx, out, totals):  # pragma: no cover - compiled; tested through its results
    """Apply a separable window to a stack of images and sum each image.

    Parameters
    ----------
    src : ndarray, shape (B, H, W)
        Images of any real dtype and any strides (tile views included).
    wy : float32 ndarray, shape (H,)
        The window's row factor.
    wx : float32 ndarray, shape (W,)
        The window's column factor; it carries any scale such as 1/255.
    out : float32 ndarray, shape (B, H, W), written
        ``src[b, r, c] * wy[r] * wx[c]``.
    totals : float64 ndarray, shape (B,), written
        The plain sum of each image's stored values (unscaled, unwindowed):
        the mean costs nothing more in this pass.
    """
    nb, h, w = src.shape
    for i in range(nb):
        total = 0.0
        for r in range(h):
            f = wy[r]
            row = src[i, r]
            o = out[i, r]
            row_total = np.float32(0.0)
            for c in range(w):
                v = np.float32(row[c])
                o[c] = v * (f * wx[c])
                row_total += v
            total += row_total
        totals[i] = total


@njit(cache=True, fastmath=_FASTMATH, nogil=True)
def spectrum_sums(spec, w, ky_down, power, moments, double_angle, peak_index):  # pragma: no cover - compiled
    """Power-weighted sums over each half spectrum in a stack, and its strongest bin.

    P = |F|^2 of each bin; the DC bin (0, 0) is left out of everything.  Every
    sum is over the *full* spectrum: each stored column but the first and,
    for an even W, the last stands for itself and its mirror, so counts twice.
    Frequencies are in cycles/pixel with y running *down* the picture (the
    caller flips the signs for y up).

    A Nyquist frequency (row H/2 of an even height, column W/2 of an even
    width) is +1/2 and -1/2 at once: it counts in kx^2 and ky^2 but not in the
    signed kx ky and sin 2t sums, where its two halves cancel.

    Parameters
    ----------
    spec : float32 ndarray, shape (B, H, 2 * (W // 2 + 1))
        The rfft2 of each image viewed as interleaved (re, im) pairs.
    w : int
        Width of the images [pixels]: fixes kx = column / w and which
        columns have a mirror.
    ky_down : float64 ndarray, shape (H,)
        Signed vertical frequency of each row [cycles/pixel], rows running down.
    power : float64 ndarray, shape (B,), written
        sum P.
    moments : float64 ndarray, shape (B, 3), written
        sum P kx^2, sum P ky^2, sum P kx ky [cycles^2/pixel^2 times power].
    double_angle : float64 ndarray, shape (B, 2), written
        sum P cos 2t, sum P sin 2t, with t the angle of the bin's wave vector.
    peak_index : int64 ndarray, shape (B,), written
        Flat index ``row * (W // 2 + 1) + column`` of the first bin holding the
        largest P, as ``np.argmax`` of the half spectrum's power gives it.
    """
    nb, h, nc2 = spec.shape
    nc = nc2 // 2
    # Per-column tables, small enough to stay in L1 for the whole stack.
    kx = np.empty(nc, np.float32)  # in the signed sums only: Nyquist is 0 there, see above
    kx2 = np.empty(nc, np.float32)
    mirror = np.empty(nc, np.float32)
    for c in range(nc):
        kx[c] = c / w
        kx2[c] = kx[c] * kx[c]
        mirror[c] = 2.0
    mirror[0] = 1.0
    if w % 2 == 0:
        mirror[nc - 1] = 1.0
        kx[nc - 1] = 0.0
    row_power = np.empty(nc, np.float32)
    bits = row_power.view(np.int32)
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
            if 2 * r == h:
                ky = np.float32(0.0)  # the Nyquist row of an even height: in ky^2 only
            row = spec[i, r]
            # First over the row: its power, and the largest one.  The maximum is
            # taken over the float bits as integers: for P >= 0 they order the
            # same, and an integer max vectorises where a float max (NaN rules)
            # does not (4x faster here).
            for c in range(nc):
                re = row[2 * c]
                im = row[2 * c + 1]
                row_power[c] = re * re + im * im
            if r == 0:
                row_power[0] = 0.0
            row_max = np.int32(0)
            for c in range(nc):
                row_max = max(row_max, bits[c])
            # Then the sums, from the row still in L1: per-row float32
            # partials (they vectorise), added up in float64.
            r0 = np.float32(0.0)
            r1 = np.float32(0.0)
            r2 = np.float32(0.0)
            rc = np.float32(0.0)
            rs = np.float32(0.0)
            for c in range(nc):
                q = mirror[c] * row_power[c]
                k = kx[c]
                k2 = kx2[c]
                r0 += q
                r1 += q * k
                r2 += q * k2
                # cos 2t = (kx^2 - ky^2) / k^2 and sin 2t = 2 kx ky / k^2.  At DC (the
                # only bin with k = 0) q is 0, so any finite 1/k^2 will do.
                q_k2 = q / max(k2 + ky2, tiny)
                rc += (k2 - ky2) * q_k2
                rs += k * q_k2
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
        power[i] = s0
        moments[i, 0] = sxx
        moments[i, 1] = syy
        moments[i, 2] = sxy
        double_angle[i, 0] = sc
        double_angle[i, 1] = ss
        peak_index[i] = best_index
