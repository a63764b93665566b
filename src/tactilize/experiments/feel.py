"""What a participant feels: ``tactilize serve``'s pen renderer, one per trial and picture.

Each trial is rendered by :class:`~tactilize.pen.PenRenderer`, the renderer
the pen page uses, with the trial's condition's profile (the paper's
experiments compare laws, so a trial never gets the page's default): the same
standby on a lift (a participant's next touch starts warm), the same split over
the pen's channels, the same resend rule and, for a profile whose rendering is
``surface``, the same pulse per bump crossed (docs/surfaces.md).

A picture of a protocol drives with its whole-picture features wherever the
pen is on it, as in the paper's experiments (its tables give one set per
picture): :class:`WholePicture` is that map.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable

from ..actuators.base import Output
from ..drive import Drive
from ..mapping import FeaturesForDrive, Profile
from ..pen import PenRenderer, PenSample, StrokeState, StrokeTracker
from ..pen.renderer import RenderResult, default_splitter
from ..surface import SurfaceModel

__all__ = ["WholePicture", "TrialPen", "Taken"]

#: ``(sample, speed_m_s, direction_rad or None)``: one sample and the stroke's state after it.
Taken = tuple[PenSample, float, "float | None"]


@dataclass(frozen=True)
class WholePicture:
    """A texture map with one set of features everywhere (a protocol picture's)."""

    features: FeaturesForDrive

    def lookup(self, x_m: float, y_m: float) -> FeaturesForDrive:
        """The picture's features, wherever ``(x_m, y_m)`` [m] is."""
        return self.features


class _LoggedTracker(StrokeTracker):
    """A stroke tracker that keeps the state after each sample of the latest batch.

    The stroke log stores every sample with the speed the stroke had then; the
    renderer asks for the batch's final state only.
    """

    def __init__(self) -> None:
        super().__init__()
        self.taken: list[Taken] = []

    def extend(self, samples: Any) -> StrokeState | None:
        self.taken = []
        for ps in samples:
            self.add(ps)
            st = self.state
            self.taken.append((ps, st.speed_m_s if st else 0.0, st.direction_rad if st else None))
        return self.state


def _unsplit(drive: Drive, n: int, state: StrokeState | None) -> list[Drive]:
    return [drive] * n


class TrialPen:
    """The renderers of one participant's pen: one per (trial, picture), one output.

    Parameters
    ----------
    output : Output or None
        The pen's actuators (``tactilize serve``'s, under its lease), or None
        when nothing is attached: the drives are still computed and logged.
    clock : callable
        ``clock() -> seconds``, monotonic, for the renderers' resend rule.

    Notes
    -----
    Each (trial, picture) keeps its own stroke, so a batch that arrives late for
    an answered trial does not disturb the stroke of the open one, and the
    stroke log's speeds are those of each picture's own stroke.  The output is
    driven by the renderer of the open trial's picture being stroked; the
    others only track.
    """

    def __init__(self, output: Output | None = None, clock: Callable[[], float] = time.monotonic) -> None:
        self.output = output
        self.clock = clock
        self.renderers: dict[tuple[int, str], PenRenderer] = {}
        self._trackers: dict[tuple[int, str], _LoggedTracker] = {}  # each renderer's own
        self._felt: PenRenderer | None = None
        # Nothing attached: no channel is driven, so the split (a phantom-sensation model
        # per batch) would be computed for nobody; the reply carries the unsplit drive.
        self._split = default_splitter(output) if output is not None else _unsplit
        self._drive: Drive | None = None  # the unsplit drive of the latest render

    def _splitter(self, drive: Drive, n: int, state: StrokeState | None) -> list[Drive]:
        self._drive = drive
        return self._split(drive, n, state)

    def _renderer(self, key: tuple[int, str], features: FeaturesForDrive, profile: Profile,
                  surface: SurfaceModel | None) -> PenRenderer:
        r = self.renderers.get(key)
        if r is None:
            tracker = self._trackers[key] = _LoggedTracker()
            r = self.renderers[key] = PenRenderer(
                WholePicture(features), profile, self.output, tracker=tracker,
                splitter=self._splitter, clock=self.clock, surface=surface,
            )
        return r

    def track(self, key: tuple[int, str], features: FeaturesForDrive, profile: Profile, samples: list[PenSample],
              surface: SurfaceModel | None = None) -> list[Taken]:
        """Follow a batch that is logged, not felt (its trial was answered); the states per sample."""
        self._renderer(key, features, profile, surface)
        tracker = self._trackers[key]
        tracker.extend(samples)
        return list(tracker.taken)

    def feel(self, key: tuple[int, str], features: FeaturesForDrive, profile: Profile, surface: SurfaceModel | None,
             samples: list[PenSample]) -> tuple[list[Taken], Drive | None, RenderResult]:
        """Render a batch of the open trial on the output.

        Returns
        -------
        taken : list
            ``(sample, speed_m_s, direction_rad)`` per sample.
        drive : Drive or None
            The drive the profile gave for the newest sample before the split
            over channels (the equivalent drive, for the surface rendering);
            None when no sample could be tracked.
        result : RenderResult
            What the renderer did (the drives the output applied, the events).
        """
        r = self._renderer(key, features, profile, surface)
        if self._felt is not r:
            if self._felt is not None:
                self._felt.yield_output()
            r.yield_output()  # the output may play another picture's drive since this one last sent
            self._felt = r
        self._drive = None
        result = r.feed(samples)
        return list(self._trackers[key].taken), self._drive, result

    def lift(self) -> None:
        """The pen left the surface: every stroke restarts, the output rests in standby."""
        for r in self.renderers.values():
            r.lift()

    def keep(self, predicate: Callable[[tuple[int, str]], bool]) -> None:
        """Forget the strokes of the (trial, picture) keys ``predicate`` rejects."""
        for key in [k for k in self.renderers if not predicate(k)]:
            r = self.renderers.pop(key)
            del self._trackers[key]
            if r is self._felt:
                r.lift()
                self._felt = None
