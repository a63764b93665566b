"""Pulse events as acceleration wavelets: what a voice coil plays in real time.

The real-time outputs (the sound card, the page's audio) get the surface
rendering's pulse events (docs/surfaces.md), not the stroke's path.  Each event
is played as the acceleration of the tip over one bump: a bump of Gaussian
profile (standard deviation sigma_b) crossed at speed v lifts the tip by
A exp(-(v t)^2 / (2 sigma_b^2)), whose second derivative is a Ricker wavelet
(the negative second derivative of a Gaussian) of width sigma_t = sigma_b / v:

    w(t) = -(1 - tau^2) exp(-tau^2 / 2),  tau = (t - t_event) / sigma_t

An event does not say its bump's width or the speed; it says when.  The width is
taken from the interval to the nearest neighbouring event, sigma_t = interval /
(sqrt(2) pi), so the wavelet's spectral peak, 1 / (sqrt(2) pi sigma_t), is the
local crossing rate: on a grating or grains (bumps as wide as their spacing) a
train of these wavelets peaks where the tip's acceleration peaks, at v f_s.
The width is kept inside the actuator's band (the peak between 20 and 1000 Hz),
which is also what bounds a lone bump's wavelet.  Amplitude is the event's
strength (its place in the felt band, pressure included), so the sound card
plays the same loudness scale as the wire; the WAV export carries the physical
acceleration, v^2 included (:mod:`.acceleration`).

The wavelet is cut at +-:data:`SPAN_SIGMAS` sigma with a raised-cosine taper over
the last sigma (the tail there is under 11 % of the peak), so a scheduled
wavelet starts a bounded time before its event.  ``web/static/pulse-worklet.js``
draws the same shape.

Units: SI (s, Hz); amplitude in [0, 1] of full scale.

References
----------
.. [1] docs/references.md, section 3 (voice-coil band).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple, Sequence

import numpy as np

from ..surface.events import MIN_INTERVAL_S
from .acceleration import VOICE_COIL_BAND_HZ

__all__ = ["Wavelet", "FrameWavelet", "SPAN_SIGMAS", "ricker", "event_wavelets", "wavelet_rows", "render_wavelets", "WaveletPlayer",
           "SAME_S", "GLIDE_S", "LATE_SIGMAS"]

#: The wavelet is drawn over +- this many standard deviations.
SPAN_SIGMAS = 3.0
_SQRT2_PI = math.sqrt(2.0) * math.pi


class Wavelet(NamedTuple):
    """One event as a wavelet: centre [s], amplitude [0, 1], width (standard deviation) [s]."""

    t_s: float
    amplitude: float
    sigma_s: float


class FrameWavelet(NamedTuple):
    """A :class:`Wavelet` on a :class:`WaveletPlayer`'s frame clock: centre [frame], amplitude
    [0, 1], width (standard deviation) [frames]."""

    centre_frame: float
    amplitude: float
    sigma_frames: float


def ricker(tau: np.ndarray) -> np.ndarray:
    """The wavelet's shape at ``tau`` standard deviations from its centre: -1 at the centre,
    0 beyond :data:`SPAN_SIGMAS`, tapered over the last one."""
    tau = np.abs(np.asarray(tau, dtype=np.float64))
    w = -(1.0 - tau * tau) * np.exp(-0.5 * tau * tau)
    edge = SPAN_SIGMAS - 1.0
    taper = np.where(tau <= edge, 1.0, 0.5 + 0.5 * np.cos(np.pi * np.clip(tau - edge, 0.0, 1.0)))
    return np.where(tau < SPAN_SIGMAS, w * taper, 0.0)


def _sigma_bounds(band_hz: tuple[float, float]) -> tuple[float, float]:
    return 1.0 / (_SQRT2_PI * band_hz[1]), 1.0 / (_SQRT2_PI * band_hz[0])


_VOICE_COIL_SIGMAS = _sigma_bounds(VOICE_COIL_BAND_HZ)


def event_wavelets(events: Sequence[Any], previous_t_s: float | None = None,
                   band_hz: tuple[float, float] = VOICE_COIL_BAND_HZ) -> list[Wavelet]:
    """One :class:`Wavelet` per pulse event (``t_s``, ``strength``), widths from the intervals.

    Parameters
    ----------
    events : sequence of PulseEvent
        Times [s] increasing.
    previous_t_s : float, optional
        Time of the event played before these [s] (its interval counts).
    band_hz : (float, float)
        The actuator's band [Hz]: the wavelets' peaks stay inside it.
    """
    lo, hi = _sigma_bounds(band_hz)
    t = [float(e.t_s) for e in events]
    n = len(t)
    out = []
    for i in range(n):
        gaps = []
        if i > 0:
            gaps.append(t[i] - t[i - 1])
        elif previous_t_s is not None:
            gaps.append(t[i] - float(previous_t_s))
        if i + 1 < n:
            gaps.append(t[i + 1] - t[i])
        gaps = [g for g in gaps if g > 0]
        sigma = min(gaps) / _SQRT2_PI if gaps else hi
        out.append(Wavelet(t[i], float(events[i].strength), min(hi, max(lo, sigma))))
    return out


def wavelet_rows(events: Sequence[Any], now_s: float) -> list[list[float]]:
    """The page's form of :func:`event_wavelets`: ``[dt_s, amplitude, sigma_s]`` per event,
    ``dt_s`` from ``now_s`` [s] (the stroke time of the newest pen sample)."""
    # The same arithmetic as event_wavelets without its Wavelet values: every surface batch
    # builds these rows for the page (tests/test_wavelets.py holds the two equal).
    lo, hi = _VOICE_COIL_SIGMAS
    t = [float(e.t_s) for e in events]
    n = len(t)
    rows = []
    for i in range(n):
        gap = math.inf
        if i > 0 and t[i] - t[i - 1] > 0:
            gap = t[i] - t[i - 1]
        if i + 1 < n and 0 < t[i + 1] - t[i] < gap:
            gap = t[i + 1] - t[i]
        sigma = gap / _SQRT2_PI if gap != math.inf else hi
        rows.append([t[i] - now_s, float(events[i].strength), min(hi, max(lo, sigma))])
    return rows


def render_wavelets(wavelets: Sequence[Wavelet], t0_s: float, n: int, sample_rate_hz: float) -> np.ndarray:
    """``n`` samples from ``t0_s`` [s] at ``sample_rate_hz`` [Hz] of the wavelets summed (offline)."""
    out = np.zeros(n)
    fs = float(sample_rate_hz)
    for w in wavelets:
        half = SPAN_SIGMAS * w.sigma_s
        a = max(0, int(math.floor((w.t_s - half - t0_s) * fs)))
        b = min(n, int(math.ceil((w.t_s + half - t0_s) * fs)) + 1)
        if a < b:
            tau = (t0_s + np.arange(a, b) / fs - w.t_s) / w.sigma_s
            out[a:b] += w.amplitude * ricker(tau)
    return out


#: A new wavelet asked for within this long [s] of one already scheduled is that one again (a
#: batch re-sends every event whose time has not come, a little moved as the prediction
#: firms; a wavelet starts :data:`SPAN_SIGMAS` before it): half the least interval events keep
#: (:data:`~tactilize.surface.events.MIN_INTERVAL_S`), so two distinct events never are.
#: A width is no measure here: the first event of a batch has no neighbour before it.
SAME_S = 0.5 * MIN_INTERVAL_S


#: A wavelet whose start has passed keeps its centre (its leading tail faded in from now) while
#: at least this many standard deviations remain before the crest; later, it plays whole from now.
LATE_SIGMAS = 1.0
#: A kept wavelet whose event is re-sent with another strength glides to it over this long [s]
#: (an event first seen at the look-ahead's far end is a bump partly seen, and weak).
GLIDE_S = 0.003


class _Item:
    """One scheduled wavelet, in frames: amplitude ``amp_from`` until ``g0``, ``amp`` from ``g1``;
    faded in (raised cosine) from ``start`` to ``fade_end`` when it starts late."""

    __slots__ = ("start", "centre", "sigma", "want", "amp", "amp_from", "g0", "g1", "fade_end")

    def __init__(self, start: int, centre: float, amp: float, sigma: float, want: float,
                 fade_end: float | None = None) -> None:
        self.start, self.centre, self.sigma, self.want = start, centre, sigma, want
        self.amp = self.amp_from = amp
        self.g0 = self.g1 = float(start)
        self.fade_end = float(start) if fade_end is None else fade_end

    def amp_at(self, frames: np.ndarray) -> np.ndarray | float:
        amp: np.ndarray | float = self.amp
        if self.amp != self.amp_from and frames[0] < self.g1:
            amp = np.interp(frames, (self.g0, self.g1), (self.amp_from, self.amp))
        if frames[0] < self.fade_end:
            u = np.clip((frames - self.start) / (self.fade_end - self.start), 0.0, 1.0)
            amp = amp * (0.5 - 0.5 * np.cos(np.pi * u))
        return amp

    def retarget(self, amp: float, now: int, glide: float) -> None:
        """Go to ``amp`` from frame ``now``: at once if not started, else over ``glide`` frames
        (never past the centre)."""
        if amp == self.amp:
            return
        if self.start >= now:
            self.amp = self.amp_from = amp
            return
        current = self.amp_at(np.array([float(now)]))
        self.amp_from = float(np.asarray(current).ravel()[0])
        self.amp, self.g0 = amp, float(now)
        self.g1 = max(float(now) + 1.0, min(float(now) + glide, self.centre))


class WaveletPlayer:
    """Wavelets scheduled on a frame clock, rendered block by block (the audio thread's side).

    :meth:`replace` drops every wavelet not yet started whose event has not fired and
    schedules new ones; one already started plays to its end (and is not scheduled again
    when a batch re-sends it: its amplitude glides to the re-sent strength).  A new one whose
    start has passed keeps its centre with its leading tail faded in from now, or, when less
    than :data:`LATE_SIGMAS` remain before its crest, plays whole from now (later).
    """

    def __init__(self, sample_rate_hz: float) -> None:
        self.sample_rate_hz = float(sample_rate_hz)
        self.frame = 0  # the next frame to render
        #: wavelets started so far
        self.started = 0
        self._items: list[_Item] = []  # by start

    def replace(self, wavelets: Sequence[FrameWavelet], fired_before: float = -math.inf) -> None:
        """Schedule wavelets on this clock, replacing those not started.

        ``fired_before`` [frame]: where the batch's newest sample falls on this clock.  A
        wavelet asked for before it belongs to an event that has fired on the stroke's clock
        (a batch re-sends only those whose time has not come): it stays, started or not.
        """
        now = self.frame
        kept = [it for it in self._items if it.start < now or it.want < fired_before]
        same = SAME_S * self.sample_rate_hz
        glide = GLIDE_S * self.sample_rate_hz
        for centre, amp, sigma in wavelets:
            match = next((it for it in kept if abs(it.want - centre) < same), None)
            if match is not None:
                match.retarget(float(amp), now, glide)
                continue
            half = SPAN_SIGMAS * sigma
            want, start, fade_end = centre, centre - half, None
            if start < now:
                if centre - now >= LATE_SIGMAS * sigma:
                    # On time, its leading tail faded in over half of what is left before the crest.
                    start, fade_end = now, now + 0.5 * (centre - now)
                else:  # too late for that: the whole wavelet, from now
                    centre, start = now + half, now
            kept.append(_Item(int(math.floor(start)), float(centre), float(amp), float(sigma), float(want),
                              fade_end))
        kept.sort(key=lambda it: it.start)
        self._items = kept

    def clear(self) -> None:
        self._items = []

    def render(self, out: np.ndarray) -> None:
        """Add the next ``len(out)`` frames into ``out``."""
        n = out.shape[0]
        f0 = self.frame
        f1 = f0 + n
        live = []
        for it in self._items:
            end = it.centre + SPAN_SIGMAS * it.sigma
            if it.start >= f1:
                live.append(it)
                continue
            if it.start >= f0:
                self.started += 1
            a, b = max(it.start, f0), min(int(math.ceil(end)) + 1, f1)
            if a < b:
                frames = np.arange(a, b, dtype=np.float64)
                out[a - f0 : b - f0] += it.amp_at(frames) * ricker((frames - it.centre) / it.sigma)
            if end >= f1:
                live.append(it)
        self._items = live
        self.frame = f1
