"""The tip's vertical acceleration along a stroke: the signal for voice coils and WAV files.

A stylus tip riding a height field h(x, y) along a path p(t) moves vertically by
z(t) = h(p(t)); its acceleration is, by the chain rule,

    z''(t) = p'(t)^T H(p) p'(t) + grad h(p) . p''(t)

which for a straight stroke is v^2 h''(s) + a h'(s) (speed v, acceleration a, s
the arc length).  Both terms are physics: the second is what a hand speeding up
or slowing down adds.  At a fixed spatial spectrum and steady speed the signal
scales as v^2 (a spatial frequency k plays at v k Hz with amplitude
v^2 (2 pi k)^2 H(k)), before the actuator's band cuts it (docs/surfaces.md,
"Voice coils and the page's audio").

How it is computed, so that stepping through pixels adds nothing:

1. The pen samples are joined by an interpolating cubic spline in time (C2): a
   polyline's velocity jumps at every sample, which would put a delta in p''
   and a tone at the pen's report rate into the signal.
2. The tip-filtered height (:class:`~tactilize.surface.model.SurfaceModel`) is
   read at every output sample with cubic B-spline interpolation
   (``scipy.ndimage.map_coordinates`` on coefficients made once per surface): a
   bilinear or nearest-pixel lookup has kinks or steps at every pixel edge, whose
   second derivative is a comb at speed / pixel pitch.
3. The height is sampled in time fast enough that nothing aliases (the output
   rate, raised to a multiple of it when the stroke is so fast that its spatial
   step would pass half the surface's profile step), band-passed to the
   actuator's band with a zero-phase Butterworth (``scipy.signal.sosfiltfilt``,
   which is also the anti-aliasing filter when decimating), and differentiated
   twice (a central difference, exact to 0.15 % at the band's top at 48 kHz).
4. Pressure, when present, scales it as it scales the events' strength
   (full at :data:`~tactilize.surface.events.REFERENCE_PRESSURE` and above).

Heights are in luminance units (docs/references.md, section 3 (luminance as
height)), so the acceleration is in luminance units per s^2, or, on a surface in
metres (a material or a relief scale, docs/surfaces.md, "Materials"), in m/s^2
with the material's micro-roughness in the heights; :func:`to_full_scale` maps it
to an audio sample in [-1, 1] (the surface's own full scale, :func:`full_scale_of`).

Units: SI (s, m, Hz).

References
----------
.. [1] docs/references.md, section 3 (voice-coil band).
"""

from __future__ import annotations

import functools
import math
import weakref
from typing import TYPE_CHECKING, Any, NamedTuple, Sequence

import numpy as np
from numpy.typing import ArrayLike

from ..errors import SignalError

if TYPE_CHECKING:  # the surface package loads scipy, which this module loads on first use
    from ..surface.model import SurfaceLike, SurfaceModel

__all__ = [
    "VOICE_COIL_BAND_HZ",
    "FULL_SCALE_ACCELERATION",
    "AccelerationSignal",
    "tip_acceleration",
    "band_limited_acceleration",
    "heights_along",
    "audio_rows",
    "to_full_scale",
    "full_scale_of",
    "spectrum",
    "spectral_peak_hz",
    "spectral_centroid_hz",
]

#: The actuator's band [Hz]: a voice coil on an audio amplifier, and what skin feels of
#: it (docs/references.md, section 3 (voice-coil band)).
VOICE_COIL_BAND_HZ = (20.0, 1000.0)
#: Acceleration played at full scale [luminance units / s^2]: a full-range sinusoidal
#: grating (amplitude 0.5) crossed at 250 Hz, the Pacinian channel's most sensitive
#: frequency (docs/references.md, section 3 (mechanoreceptor bands)).
FULL_SCALE_ACCELERATION = 0.5 * (2 * math.pi * 250.0) ** 2
#: Butterworth order of the band-pass (applied forward and back: twice this).
_ORDER = 4
#: Extra signal computed on each side of a block where another block joins it, so the
#: filter's edges fall outside what is returned [s]: the 20 Hz band edge rings for tens of
#: ms, and blocks join within a millionth of the signal's peak.
_MARGIN_S = 0.25
#: ...and at the span's two ends, where the span's own edge is what it is [s].
_END_MARGIN_S = 0.05
#: Output samples computed at once (10.9 s at 48 kHz).
_CHUNK = 1 << 19
#: Most the height is oversampled by (a stroke's fastest segment sets it).
_MAX_OVERSAMPLE = 8

# Spline coefficients per surface, made on first use and kept while the surface lives.
_COEFFS: "weakref.WeakKeyDictionary[SurfaceModel, np.ndarray]" = weakref.WeakKeyDictionary()


class AccelerationSignal(NamedTuple):
    """The tip's vertical acceleration sampled in time.

    Attributes
    ----------
    t0_s : float
        Time of the first sample [s], on the stroke's clock.
    sample_rate_hz : float
        [Hz].
    samples : ndarray of float64
        Acceleration [luminance units / s^2], band-limited to ``band_hz``.
    band_hz : (float, float)
        The band it was limited to [Hz].
    """

    t0_s: float
    sample_rate_hz: float
    samples: np.ndarray
    band_hz: tuple[float, float]

    @property
    def duration_s(self) -> float:
        return self.samples.size / self.sample_rate_hz


def _coefficients(surface: SurfaceModel) -> np.ndarray:
    """Cubic B-spline coefficients of the surface's tip-filtered height (cached per surface)."""
    try:
        return _COEFFS[surface]
    except (KeyError, TypeError):
        pass
    from scipy.ndimage import spline_filter

    c = spline_filter(np.asarray(surface.height, dtype=np.float64), order=3, mode="mirror")
    try:
        _COEFFS[surface] = c
    except TypeError:  # not weak-referenceable: recompute next time
        pass
    return c


def _base(surface: SurfaceLike) -> tuple[SurfaceModel, float, float]:
    """The SurfaceModel under a mirrored view (:class:`~tactilize.surface.straight.MirroredSurface`),
    and the view's folding width and height [m] (0 when not mirrored)."""
    from ..surface.model import SurfaceModel
    from ..surface.straight import MirroredSurface

    inner, w, h = (surface.surface, surface.w, surface.h) if isinstance(surface, MirroredSurface) else (surface, 0.0, 0.0)
    if not isinstance(inner, SurfaceModel):
        raise SignalError("<surface>", "the acceleration signal needs a SurfaceModel (one picture's height field)")
    return inner, float(w), float(h)


def heights_along(surface: SurfaceLike, x_m: np.ndarray, y_m: np.ndarray) -> np.ndarray:
    """Tip-filtered height at display positions [m] by cubic B-spline interpolation
    (mirrored beyond the picture's edges under a
    :class:`~tactilize.surface.straight.MirroredSurface`) [luminance units]."""
    from scipy.ndimage import map_coordinates

    from ..surface.straight import fold_into

    base, w, h = _base(surface)
    x = fold_into(x_m, w)
    y = fold_into(y_m, h)
    px, py = base.display_pitch_m
    # Pixel centres sit at (i + 0.5) pitch.
    coords = np.stack([y / py - 0.5, x / px - 0.5])
    heights: np.ndarray = map_coordinates(_coefficients(base), coords, order=3, mode="mirror", prefilter=False)
    if base.micro is not None:  # a material's roughness below the pixels
        heights = heights + base.micro_at(x, y)
    return heights


def _path_spline(t: np.ndarray, xy: np.ndarray) -> Any:
    from scipy.interpolate import make_interp_spline

    return make_interp_spline(t, xy, k=min(3, t.size - 1), axis=0)


def tip_acceleration(
    surface: SurfaceLike,
    t_s: ArrayLike,
    x_m: ArrayLike,
    y_m: ArrayLike,
    pressure: Sequence[float | None] | ArrayLike | None = None,
    *,
    sample_rate_hz: float = 48_000.0,
    start_s: float | None = None,
    end_s: float | None = None,
    band_hz: tuple[float, float] = VOICE_COIL_BAND_HZ,
) -> AccelerationSignal:
    """The tip's vertical acceleration along a stroke, band-limited (module docstring).

    Parameters
    ----------
    surface : SurfaceModel or MirroredSurface
        The picture's tip-filtered height field (or a mirrored view of one).
    t_s, x_m, y_m : sequence of float
        Pen samples: times [s], strictly increasing; display positions [m] from the
        top-left, y down.
    pressure : float, sequence of float or None, optional
        Pen pressure in [0, 1], one value or one per sample (None where unknown).
    sample_rate_hz : float
        Output rate [Hz].
    start_s, end_s : float, optional
        The span returned [s]; the samples' span by default.  Outside the samples the
        pen rests where it was.
    band_hz : (float, float)
        The actuator's band [Hz].

    Returns
    -------
    AccelerationSignal

    Raises
    ------
    SignalError
        Fewer than two samples, times that do not increase, values that are not
        finite, a band outside (0, sample_rate / 2).
    """
    t = np.asarray(t_s, dtype=np.float64)
    xy = np.stack([np.asarray(x_m, dtype=np.float64), np.asarray(y_m, dtype=np.float64)], axis=1)
    if t.ndim != 1 or t.size < 2 or xy.shape[0] != t.size:
        raise SignalError("<stroke>", "the acceleration signal needs at least two samples of t, x, y")
    if not (np.isfinite(t).all() and np.isfinite(xy).all()):
        raise SignalError("<stroke>", "times and positions must be finite numbers")
    if not (np.diff(t) > 0).all():
        raise SignalError("<stroke>", "times must increase")
    fs = float(sample_rate_hz)
    lo, hi = float(band_hz[0]), float(band_hz[1])
    if not (fs > 0 and 0 < lo < hi < fs / 2):
        raise SignalError("<band>", f"needs 0 < {lo:g} < {hi:g} < half the sample rate ({fs / 2:g}) Hz")
    start = float(t[0] if start_s is None else start_s)
    end = float(t[-1] if end_s is None else end_s)
    n = max(int(round((end - start) * fs)), 0)
    if n == 0:
        return AccelerationSignal(start, fs, np.zeros(0), (lo, hi))
    base, _, _ = _base(surface)
    # Oversample when the stroke is fast enough for its step per sample to pass half the
    # surface's profile step (content up to the pixel's own rate must not alias).
    speed_max = float(np.max(np.hypot(*np.diff(xy, axis=0).T) / np.diff(t)))
    # (At most _MAX_OVERSAMPLE: one wild sample must not make the work explode.)
    m = min(_MAX_OVERSAMPLE, max(1, int(math.ceil(speed_max / (fs * 0.5 * base.step_m)))))
    rate = fs * m
    inner, outer = int(round(_MARGIN_S * rate)), int(round(_END_MARGIN_S * rate))
    spline = _path_spline(t, xy)
    acc = np.empty(n)
    # Blocks of _CHUNK output samples, with margins on either side, so a ten-minute stroke
    # needs tens of megabytes, not gigabytes; the filter's edges fall in the margins.
    for a in range(0, n, _CHUNK):
        b = min(n, a + _CHUNK)
        lo_pad, hi_pad = (inner if a > 0 else outer), (inner if b < n else outer)
        grid = start + (np.arange(a * m - lo_pad, b * m + hi_pad) / rate)
        pos = spline(np.clip(grid, t[0], t[-1]))  # at rest before the first sample and after the last
        h = heights_along(surface, pos[:, 0], pos[:, 1])
        acc[a:b] = band_limited_acceleration(h, rate, (lo, hi))[lo_pad : lo_pad + (b - a) * m : m]
    scale = _pressure_scale(pressure, t, start + np.arange(n) / fs)
    if scale is not None:
        acc = acc * scale
    return AccelerationSignal(start, fs, acc, (lo, hi))


def band_limited_acceleration(heights: np.ndarray, sample_rate_hz: float,
                              band_hz: tuple[float, float] = VOICE_COIL_BAND_HZ) -> np.ndarray:
    """Second time-derivative of heights sampled at ``sample_rate_hz`` [Hz], band-passed to
    ``band_hz`` [Hz] (zero phase), in height units per s^2.

    The band-pass comes first: it is the anti-aliasing filter of any decimation after,
    and a central difference of a signal below the band's top is exact to
    (2 pi f / rate)^2 / 12 (0.15 % at 1 kHz and 48 kHz).
    """
    from scipy.signal import sosfiltfilt

    rate = float(sample_rate_hz)
    sos = _band_pass(rate, float(band_hz[0]), float(band_hz[1]))
    hb = sosfiltfilt(sos, np.asarray(heights, dtype=np.float64))
    acc = np.empty_like(hb)
    acc[1:-1] = (hb[2:] - 2.0 * hb[1:-1] + hb[:-2]) * (rate * rate)
    acc[0], acc[-1] = acc[1], acc[-2]
    return acc


@functools.lru_cache(maxsize=16)
def _band_pass(rate: float, lo: float, hi: float) -> np.ndarray:
    """The Butterworth band-pass as second-order sections (designing it costs as much as
    filtering a second of signal)."""
    from scipy.signal import butter

    return butter(_ORDER, (lo, hi), btype="bandpass", fs=rate, output="sos")


def _pressure_scale(pressure: Any, t: np.ndarray, grid: np.ndarray) -> np.ndarray | float | None:
    from ..surface.events import REFERENCE_PRESSURE

    if pressure is None:
        return None
    if np.isscalar(pressure):
        return min(1.0, max(0.0, float(pressure)) / REFERENCE_PRESSURE)  # type: ignore[arg-type]
    p = np.array([np.nan if v is None else float(v) for v in pressure], dtype=np.float64)
    known = np.isfinite(p)
    if not known.any():
        return None
    pk = np.interp(grid, t[known], p[known])
    return np.minimum(1.0, np.maximum(0.0, pk) / REFERENCE_PRESSURE)


def full_scale_of(surface: SurfaceLike) -> float:
    """Acceleration at full scale for ``surface`` [m/s^2 on a surface in metres, else luminance
    units / s^2]: its own (``SurfaceModel.full_scale_acceleration``) or
    :data:`FULL_SCALE_ACCELERATION`."""
    from ..surface.straight import MirroredSurface

    base = surface.surface if isinstance(surface, MirroredSurface) else surface
    own = getattr(base, "full_scale_acceleration", None)
    return FULL_SCALE_ACCELERATION if own is None else float(own)


def to_full_scale(signal: AccelerationSignal, gain: float = 1.0,
                  full_scale: float = FULL_SCALE_ACCELERATION) -> tuple[np.ndarray, int]:
    """Audio samples in [-1, 1]: acceleration over ``full_scale`` (:func:`full_scale_of` the
    surface) times ``gain``, clipped; returns them and how many were clipped."""
    x = signal.samples * (gain / full_scale)
    clipped = int(np.count_nonzero(np.abs(x) > 1.0))
    return np.clip(x, -1.0, 1.0), clipped


def spectrum(signal: AccelerationSignal | np.ndarray, sample_rate_hz: float | None = None,
             resolution_hz: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Welch power spectral density of a signal: (frequencies [Hz], density [unit^2 / Hz])."""
    from scipy.signal import welch

    if isinstance(signal, AccelerationSignal):
        x, fs = signal.samples, signal.sample_rate_hz
    else:
        x, fs = np.asarray(signal, dtype=np.float64), float(sample_rate_hz or 0.0)
    nper = min(x.size, int(2 ** math.ceil(math.log2(fs / resolution_hz))))
    return welch(x, fs=fs, nperseg=nper, window="hann")


def spectral_peak_hz(freqs: np.ndarray, power: np.ndarray, band_hz: tuple[float, float] = VOICE_COIL_BAND_HZ) -> float:
    """Frequency of the strongest bin within ``band_hz`` [Hz]."""
    sel = (freqs >= band_hz[0]) & (freqs <= band_hz[1])
    return float(freqs[sel][np.argmax(power[sel])])


def spectral_centroid_hz(freqs: np.ndarray, power: np.ndarray,
                         band_hz: tuple[float, float] = VOICE_COIL_BAND_HZ) -> float:
    """Power-weighted mean frequency within ``band_hz`` [Hz] (0 for silence)."""
    sel = (freqs >= band_hz[0]) & (freqs <= band_hz[1])
    total = float(power[sel].sum())
    return float((freqs[sel] * power[sel]).sum() / total) if total > 0 else 0.0


def audio_rows(surface: SurfaceModel, speeds_mm_s: Sequence[float], duration_s: float = 1.0,
               sample_rate_hz: float = 48_000.0) -> list[dict[str, float]]:
    """The signal of a straight stroke (along +x, from the picture's centre, mirrored beyond
    its edges) at each speed: spectral peak and centroid [Hz] in the band, RMS and peak
    [share of full scale], the share of samples clipped (``profile report --audio``)."""
    from ..surface.straight import MirroredSurface

    rows = []
    view = MirroredSurface(surface)
    for v in speeds_mm_s:
        t = np.arange(0.0, duration_s + 0.2, 1 / 240.0) - 0.1
        x = surface.width_m / 2 + v * 1e-3 * t
        y = np.full(t.size, surface.height_m / 2)
        sig = tip_acceleration(view, t, x, y, sample_rate_hz=sample_rate_hz, start_s=0.0, end_s=duration_s)
        f, p = spectrum(sig)
        a = sig.samples / full_scale_of(surface)
        rows.append({
            "speed_mm_s": float(v),
            "peak_hz": spectral_peak_hz(f, p, sig.band_hz),
            "centroid_hz": spectral_centroid_hz(f, p, sig.band_hz),
            "rms_full_scale": float(np.sqrt(np.mean(a * a))),
            "peak_full_scale": float(np.max(np.abs(a))),
            "clipped_share": float(np.mean(np.abs(a) > 1.0)),
        })
    return rows
