"""The protocol check: a condition the wire would not follow never reaches a participant.

Run by :func:`.design_toml.design_from_toml` on every condition when a protocol
is loaded (``experiment run``, ``simulate``, the built-ins), so a bad law fails
with one line before anyone sits down.
"""

from __future__ import annotations

import functools

from ..actuators.sma.envelope import default_envelope
from ..actuators.felt import feel
from ..mapping import DriveFeatures
from .errors import DesignError

__all__ = ["check_condition", "CHECK_SPEEDS_M_S", "CHECK_STROKE_S"]

#: Length of the simulated stroke [s]: enough pulses to judge (the settled window is its last two thirds).
CHECK_STROKE_S = 0.4

#: Pen speeds [m/s] a condition is tried at; the middle one is the stroke the wire is simulated on.
CHECK_SPEEDS_M_S = (0.01, 0.03, 0.06, 0.12, 0.2)


@functools.lru_cache(maxsize=512)
def _follows(drive) -> bool:
    return feel(drive, duration_s=CHECK_STROKE_S).follows


def check_condition(proto, cond, source: str) -> None:
    """Refuse a condition the wire would not follow.

    1. Silence: every image at every speed of :data:`CHECK_SPEEDS_M_S` through
       the condition's profile and the default safety envelope gives no pulse
       (``k2 = -30`` loads as a law but is 0 Hz everywhere).
    2. The wire: each image's drive at 60 mm/s is played on the simulated
       paper wire with its controller and envelope (:func:`~tactilize.actuators.felt.feel`),
       and every pulse must move the pin (one simulation per condition: the
       image whose drive pulses fastest, the hardest to follow).
    Images given by a picture file are represented by their stated (or default)
    features here; they are measured when the flow starts.
    """
    profile = proto.profile(cond.id)
    envelope = default_envelope()
    heard = False
    hardest = None  # (image id, drive): the mid-speed drive with the highest pulse rate
    for im in proto.images:
        feats = DriveFeatures(im.spatial_frequency_per_m, im.spectral_intensity, im.orientation_deg, im.anisotropy)
        drives = [envelope.apply(profile.drive(feats, speed_m_s=v)) for v in CHECK_SPEEDS_M_S]
        heard = heard or any(not d.is_off and d.pulse_frequency_hz > 0 and d.pulse_width_s > 0 and d.amplitude > 0
                             for d in drives)
        mid = drives[len(drives) // 2]
        if not mid.is_off and (hardest is None or mid.pulse_frequency_hz > hardest[1].pulse_frequency_hz):
            hardest = (im.id, mid)
    # One simulation per condition, on its fastest pulse train: the one the wire is least likely to follow.
    if heard and hardest is not None and not _follows(hardest[1]):
        im_id, mid = hardest
        raise DesignError(source, f"condition {cond.id} ({cond.label}): the wire would not follow its drive on "
                            f"{im_id} at 60 mm/s ({mid.pulse_frequency_hz:.0f} Hz, "
                            f"{mid.pulse_width_s * 1e3:.2f} ms); check its law coefficients")
    if not heard:
        raise DesignError(source, f"condition {cond.id} ({cond.label}) is silent: no pulses at any image and speed "
                            f"{min(CHECK_SPEEDS_M_S) * 1e3:g} .. {max(CHECK_SPEEDS_M_S) * 1e3:g} mm/s after the "
                            "controller and the safety envelope; check its law coefficients")
