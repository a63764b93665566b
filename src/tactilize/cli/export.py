"""``tactilize export``: a stroke (recorded or synthetic) on a picture, as files.

The stroke runs through the pen server's path (:func:`tactilize.export.run_stroke`):
tracker, texture map, profile, and the simulated SMA wire's controller and
envelope; the chosen format is rendered from the drive over time, or, for the
``surface`` rendering, the parametric formats from the bumps the stroke crosses.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

from ..errors import TactilizeError, check_finite, check_output_path
from .materials import choice_of, describe_relief, surface_only

if TYPE_CHECKING:
    from ..surface import SurfaceModel


def export_stroke(opt: dict[str, Any]) -> tuple[dict[str, Any], str]:
    """Run the export the options ask for; the JSON summary and the line to print."""
    from ..export import FORMATS, export, read_stroke, run_stroke, synthetic_stroke
    from ..image import load_image
    from ..mapping import Profile
    from ..maps.texturemap import texture_map
    from ..surface.rendering import rendering_for

    check_output_path(opt["out_path"])  # before the rendering, which may take seconds
    fmt = opt["fmt"].lower()
    if fmt not in FORMATS:
        raise TactilizeError("--format", f"unknown format {opt['fmt']!r} (use one of: {', '.join(FORMATS)})")
    if (opt["stroke_path"] is None) == (opt["speed_mm_s"] is None):
        raise TactilizeError("--stroke/--speed", "give a stroke file or a steady --speed, one of them")
    if opt["dpi"] is not None and opt["width_mm"] is not None:
        raise TactilizeError("--dpi/--width-mm", "give one of them, not both")
    duration = check_finite(opt["duration_s"], "--duration", above=0.0, maximum=600.0, unit="s")
    direction = check_finite(opt["direction_deg"], "--direction", unit="deg")
    profile = Profile.resolve(opt["profile_name"])
    choice = choice_of(opt.get("material_name"), opt.get("relief_mm"))
    surface_only(choice, profile)
    img = load_image(opt["image"], dpi=opt["dpi"], width_mm=opt["width_mm"])
    tmap = texture_map(img)
    # The picture's surface, made only by a rendering that reads it.
    rendering = rendering_for(profile, image=img, **choice.surface_kwargs())
    surface = cast("SurfaceModel | None", rendering.surface)
    extra: dict[str, Any] = {"image": opt["image"], "profile": profile.name, "rendering": rendering.name}
    if not choice.picture_only:
        extra.update(describe_relief(surface, choice))
    if opt["stroke_path"] is not None:
        stroke = read_stroke(opt["stroke_path"], tmap.width_m, tmap.height_m)
        extra["stroke"] = opt["stroke_path"]
        tl = run_stroke(stroke, tmap, profile, meta=extra, surface=surface)
    else:
        speed = check_finite(opt["speed_mm_s"], "--speed", minimum=0.0, unit="mm/s")
        stroke = synthetic_stroke(tmap.width_m, tmap.height_m, speed * 1e-3, duration, direction)
        extra.update(speed_mm_s=speed, direction_deg=direction)
        tl = run_stroke(stroke, tmap, profile, start_s=0.0, end_s=duration, meta=dict(extra), mirror=True,
                        surface=surface)
    limits = profile.limits.to_dict()
    tl.meta.setdefault("min_frequency_hz", limits.get("min_frequency_hz", 0.0))
    tl.meta.setdefault("max_frequency_hz", limits.get("max_frequency_hz", 300.0))
    source: Any = tl
    if fmt == "wav":  # a surface profile's WAV: the tip's acceleration
        from ..export.wav import stroke_wav_source

        source = stroke_wav_source(tl, stroke, surface, opt["drive_kind"], synthetic=opt["stroke_path"] is None)
    path = export(source, opt["out_path"], fmt, drive=opt["drive_kind"], **extra)
    feat = tmap.whole
    first = tl.drives(opt["drive_kind"])[0]
    freqs = [d.pulse_frequency_hz for d in tl.drives(opt["drive_kind"]) if not d.is_off]
    doc = {
        "path": str(path),
        "format": fmt,
        "drive": opt["drive_kind"],
        "duration_s": tl.end_s,
        "frames": len(tl.t_s),
        "drive_changes": len(tl.changes(opt["drive_kind"])),
        "spatial_frequency_per_m": feat.spatial_frequency_per_m,
        "spectral_intensity": feat.spectral_intensity,
        "min_frequency_hz": min(freqs) if freqs else 0.0,
        "max_frequency_hz": max(freqs) if freqs else 0.0,
        **extra,
        **first.to_dict(),
    }
    text = (
        f"wrote {path} ({fmt}, {tl.end_s:g} s, {len(tl.t_s)} frames, {doc['drive_changes']} drive changes, "
        f"{opt['drive_kind']} drive): {doc['min_frequency_hz']:.1f} .. {doc['max_frequency_hz']:.1f} Hz"
    )
    if source is not tl:  # the WAV holds the tip's acceleration, not the drive
        from ..synthesis import DEFAULT_SAMPLE_RATE_HZ

        x, clipped = source.samples(DEFAULT_SAMPLE_RATE_HZ, 1)  # what export() wrote (made once)
        doc.update(signal="tip_acceleration", peak_full_scale=float(abs(x).max(initial=0.0)), clipped_samples=clipped)
        text = (f"wrote {path} (wav, {tl.end_s:g} s): the tip's acceleration, peak {doc['peak_full_scale']:.3f} of "
                f"full scale, {clipped} samples clipped")
    else:
        doc.update(_event_summary(tl, fmt, opt["drive_kind"]))
        if "transients" in doc:
            n = doc["continuous_runs"]
            text += (f"; {doc['bumps']} bumps: {doc['transients']} transients, "
                     f"{n} continuous stretch{'' if n == 1 else 'es'}")
    return doc, text


def _event_summary(tl: Any, fmt: str, kind: str) -> dict[str, Any]:
    """How a parametric format plays the stroke's events (a stroke's bumps, a steady drive's
    pulses): transients and continuous stretches."""
    from ..export.events import HJIF_TRANSIENT_S, PHONE_TRANSIENT_S, plan_events, timeline_events

    events = timeline_events(tl, kind)
    out: dict[str, Any] = {"bumps": len(events)}
    if fmt in ("ahap", "android", "haptic", "hjif"):
        plan = plan_events(events, HJIF_TRANSIENT_S if fmt == "hjif" else PHONE_TRANSIENT_S, tl.end_s)
        out.update(transients=len(plan.transients), continuous_runs=len(plan.runs))
    return out
