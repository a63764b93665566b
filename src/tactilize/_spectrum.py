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
def window_into(src, wy, wx, out, totals):  # pragma: no cover - compiled; tested through its results
    """out[b, r, c] = src[b, r, c] * wy[r] * wx[c], as float32, and totals[b] = sum of src[b].

    ``src`` (B, H, W) of any real dtype and any strides; ``wy`` (H,) and
    ``wx`` (W,) float32 (``wx`` carries any scale such as 1/255); ``out``
    (B, H, W) float32; ``totals`` (B,) float64, the plain sums of the
    unscaled values (for the mean, in the same pass).
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
        bin's angle (y down) and P = |F|^2.  A Nyquist frequency (row H/2
        of an even height, column W/2 of an even width) is +1/2 and -1/2 at
        once, so it counts in kx^2 and ky^2 but not in the signed kx ky and
        sin 2t sums (where the two would cancel).
    peak_index : int64 array (B,), written
        Flat index (row * (W // 2 + 1) + column) of the first bin holding the
        largest P, as ``argmax`` gives it.
    """
    nb, h, nc2 = spec.shape
    nc = nc2 // 2
    kx = np.empty(nc, np.float32)  # in the cross terms (kx ky): Nyquist has no sign, see above
    kx2 = np.empty(nc, np.float32)
    weight = np.empty(nc, np.float32)
    for c in range(nc):
        kx[c] = c / w
        kx2[c] = kx[c] * kx[c]
        weight[c] = 2.0
    weight[0] = 1.0
    if w % 2 == 0:
        weight[nc - 1] = 1.0
        kx[nc - 1] = 0.0
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
            if 2 * r == h:
                ky = np.float32(0.0)  # the Nyquist row of an even height: in ky^2 only
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


# Columns of the table analyse_spectra writes, one row per image.
COLUMNS = (
    "kx_px", "ky_px", "spectral_intensity", "peak_amplitude", "mean_level", "periodicity", "contrast",
    "mxx", "myy", "mxy", "txx", "tyy", "txy", "flat",
)
N_COLUMNS = len(COLUMNS)

# 2-D periodic Hann window: coherent gain 1/2 per axis, power gain 3/8 per axis.
HANN_CG2 = 0.25
HANN_PG2 = (3.0 / 8.0) ** 2


@njit(cache=True, fastmath=_FASTMATH, nogil=True)
def _hann_response(d):  # pragma: no cover - compiled
    """|DFT| of a periodic Hann window at offset d bins (|d| <= 1/2), normalised to 1 at d = 0."""
    if d == 0.0:
        return 1.0
    x = np.pi * d
    return np.sin(x) / x / (1.0 - d * d)


@njit(cache=True, fastmath=_FASTMATH, nogil=True)
def _hann_offset(a_minus, a0, a_plus):  # pragma: no cover - compiled
    """Sub-bin offset of a tone from three Hann-windowed DFT magnitudes.

    For a periodic Hann window and a single tone, the ratio a of the larger
    neighbour to the peak gives the offset exactly: d = (2a - 1) / (a + 1).
    """
    right = a_plus >= a_minus
    a = (a_plus if right else a_minus) / a0 if a0 > 0 else 0.0
    d = min(0.5, max(0.0, (2.0 * a - 1.0) / (a + 1.0)))
    return d if right else -d


@njit(cache=True, fastmath=_FASTMATH, nogil=True)
def _magnitude(spec, i, ky, kx, h, nc):  # pragma: no cover - compiled
    """|F| at signed bin (ky, kx) of image i's half spectrum; 0 outside it and at DC.

    Hermitian symmetry gives the bins left of the stored half (kx < 0).
    """
    if kx < 0:
        ky = -ky
        kx = -kx
    ky %= h
    if kx >= nc or (ky == 0 and kx == 0):
        return 0.0
    re = np.float64(spec[i, ky, 2 * kx])
    im = np.float64(spec[i, ky, 2 * kx + 1])
    return np.sqrt(re * re + im * im)


@njit(cache=True, fastmath=_FASTMATH, nogil=True)
def analyse_spectra(spec, w, means, ky_down, flat_variance, intensity_size, table):  # pragma: no cover - compiled
    """Every per-image number of the feature analysis, from the windowed spectra.

    Parameters
    ----------
    spec : float32 array (B, H, 2 * (W // 2 + 1)), modified
        The rfft2 of each Hann-windowed image as interleaved (re, im) pairs.
        The mean's share is removed from the bins around DC.
    w : int
        Width of the images [pixels].
    means : float64 array (B,)
        Each image's plain mean grey level.
    ky_down : float64 array (H,)
        Signed vertical frequency of each row [cycles/pixel], rows running down.
    flat_variance : float
        Grey-level variance at or below which an image counts as constant.
    intensity_size : int
        Number of pixels for which the spectral intensity is given.
    table : float64 array (B, N_COLUMNS), written
        One row per image in the order of :data:`COLUMNS`: the dominant wave
        vector [cycles/pixel] (y up), i_s, the sinusoid's amplitude and the
        mean [grey levels], periodicity, RMS contrast, the normalised second
        moments [cycles^2/pixel^2] and orientation tensor (y up), and 1.0 for
        an image with no AC content (0.0 otherwise).
    """
    nb, h, nc2 = spec.shape
    nc = nc2 // 2
    n = h * w
    sums = np.empty((nb, 6))
    peak = np.empty(nb, np.int64)
    for i in range(nb):
        # The mean is removed where the window spreads it: the periodic Hann
        # window's DFT is exactly (N/2, -N/4, -N/4) on bins (0, +1, -1), so only
        # the 3 x 2 stored bins around DC hold it.  The plain mean, not the DC
        # bin of the windowed image: a texture one cycle across leaks into that
        # bin, and its peak came out 1.5 bins instead of 1.
        mean = means[i]
        for r, ty in ((0, h / 2.0), (1, -h / 4.0), (h - 1, -h / 4.0)):
            for c, tx in ((0, w / 2.0), (1, -w / 4.0)):
                spec[i, r, 2 * c] -= np.float32(mean * ty * tx)
    spectrum_sums(spec, w, ky_down, sums, peak)
    for i in range(nb):
        s0 = sums[i, 0]
        sxx = sums[i, 1]
        syy = sums[i, 2]
        sxy_down = sums[i, 3]
        cos2t = sums[i, 4]
        sin2t = sums[i, 5]
        iy = peak[i] // nc
        kx0 = peak[i] % nc
        ky0 = iy if iy <= h // 2 else iy - h
        a0 = _magnitude(spec, i, ky0, kx0, h, nc)
        left = _magnitude(spec, i, ky0, kx0 - 1, h, nc)
        right = _magnitude(spec, i, ky0, kx0 + 1, h, nc)
        up = _magnitude(spec, i, ky0 - 1, kx0, h, nc)
        down = _magnitude(spec, i, ky0 + 1, kx0, h, nc)
        # Power in the peak's 3 x 3 neighbourhood (the mirror peak holds as much again).
        peak_power = 0.0
        for dy in range(-1, 2):
            for dx in range(-1, 2):
                m = _magnitude(spec, i, ky0 + dy, kx0 + dx, h, nc)
                peak_power += m * m
        dx = _hann_offset(left, a0, right)
        dy = _hann_offset(up, a0, down)
        # Amplitude of the sinusoid: undo the window's coherent gain and scalloping loss.
        amp = 2.0 * a0 / (n * HANN_CG2 * _hann_response(dx) * _hann_response(dy))
        variance = s0 / (n * n * HANN_PG2)
        mean = means[i]
        f0 = 255.0 * mean * intensity_size
        fk = 255.0 * 0.5 * amp * intensity_size
        i_s = min(1.0, max(0.0, np.log1p(fk) / np.log1p(f0))) if f0 > 0 else 0.0
        safe = s0 if s0 > 0 else 1.0
        row = table[i]
        row[0] = (kx0 + dx) / w
        row[1] = -(ky0 + dy) / h  # y up
        row[2] = i_s
        row[3] = amp
        row[4] = mean
        row[5] = min(1.0, 2.0 * peak_power / safe)
        row[6] = np.sqrt(max(variance, 0.0))
        row[7] = sxx / safe
        row[8] = syy / safe
        row[9] = -sxy_down / safe  # y up
        row[10] = 0.5 + 0.5 * cos2t / safe
        row[11] = 0.5 - 0.5 * cos2t / safe
        row[12] = -0.5 * sin2t / safe  # y up
        row[13] = 1.0 if (variance <= flat_variance or s0 <= 0) else 0.0
