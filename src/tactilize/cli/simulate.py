"""The ``simulate`` and ``envelope`` commands' work: parse-checked options in, a JSON
document and a text report out (the click layer in ``cli.py`` only prints them)."""

from __future__ import annotations

import math
from typing import Any

from ..errors import TactilizeError, check_finite
from .materials import choice_of, describe_relief, surface_only

__all__ = ["simulate_stroke", "simulate_raw", "envelope_table"]


def _finite(name: str, value: float | None, *, positive: bool = True) -> None:
    if value is not None:
        check_finite(value, f"--{name}", above=0.0 if positive else None, minimum=None if positive else 0.0)


def _wire_and_circuit(opt: dict[str, Any]):
    from . import _circuit_option, _wire_option

    spec = _wire_option(opt["wire"], opt["length_mm"])
    return spec, _circuit_option(opt["circuit"], spec)


def simulate_stroke(opt: dict[str, Any]) -> tuple[dict[str, Any], str]:
    """A steady stroke on a texture through the pen's whole path (see ``tactilize simulate``)."""
    from ..actuators.felt import feel
    from ..features import extract_features
    from ..mapping import Profile

    if opt["texture_id"] is not None and opt["image_path"] is not None:
        raise TactilizeError("--texture/--image", "give one of them, not both")
    if opt["speed_mm_s"] is None:
        raise TactilizeError("--speed", "give the stroking speed in mm/s")
    if opt["plot_path"]:
        # The stroke's report keeps no traces to draw; saying so beats exiting 0 with no file.
        raise TactilizeError("--plot", "draws the raw mode only (--frequency, --pulse-width-ms, --current-ma), "
                                       "not a stroke on --texture/--image")
    _finite("speed", opt["speed_mm_s"], positive=False)
    _finite("duration", opt["duration_s"])
    if opt["duration_s"] is not None and opt["duration_s"] > 600:
        raise TactilizeError("--duration", f"at most 600 s, got {opt['duration_s']}")
    if opt["direction_deg"] is not None:
        check_finite(opt["direction_deg"], "--direction", unit="deg")
    if opt["texture_id"] is not None:
        from ..data import get_texture, texture_ids

        source = opt["texture_id"]
        try:
            img = get_texture(source).image
        except KeyError:
            raise TactilizeError(f"--texture {source}", f"no such texture (known: {', '.join(texture_ids())})") from None
    else:
        from ..image import load_image

        if opt["dpi"] is not None and opt["width_mm"] is not None:
            raise TactilizeError("--dpi/--width-mm", "give one of them, not both")
        source = opt["image_path"]
        img = load_image(source, dpi=opt["dpi"], width_mm=opt["width_mm"])
    spec, circuit = _wire_and_circuit(opt)
    profile = Profile.resolve(opt["profile_name"])
    choice = choice_of(opt.get("material_name"), opt.get("relief_mm"))
    surface_only(choice, profile)
    feat = extract_features(img)
    direction = None if opt["direction_deg"] is None else math.radians(opt["direction_deg"])
    from ..surface.rendering import rendering_for

    rendering = rendering_for(profile, image=img, **choice.surface_kwargs())
    drive = rendering.steady_drive(feat, opt["speed_mm_s"] / 1e3, direction)
    report = feel(drive, spec, circuit, standby=opt["standby"], duration_s=opt["duration_s"],
                  closed_loop=not opt["open_loop"])
    doc = {
        "source": source,
        "profile": profile.name,
        "rendering": rendering.name,
        **({} if choice.picture_only else describe_relief(rendering.surface, choice)),
        "speed_mm_s": opt["speed_mm_s"],
        "wire": spec.name,
        "circuit": circuit.name,
        "spatial_frequency_per_m": feat.spatial_frequency_per_m,
        "spectral_intensity": feat.spectral_intensity,
        "strength": drive.strength,
        "drive_clamped": list(drive.clamped),
        **report.to_dict(),
    }
    first = "never" if report.first_follow_ms == math.inf else f"{report.first_follow_ms:.1f} ms"
    # A drive that is off (a pen at rest on a surface, a picture without a period) has no strength.
    strength = "none (off)" if drive.strength is None else f"{drive.strength:.2f}"
    text = (
        f"{source} at {opt['speed_mm_s']:g} mm/s, profile {profile.name}, {spec.name} wire on {circuit.name}\n"
        f"  pulse frequency     {report.pulse_frequency_hz:.1f} Hz (the profile's), strength {strength}\n"
        f"  follows             {'yes' if report.follows else 'no'} ({report.pulses_followed}/{report.pulses} pulses)\n"
        f"  displacement p-p    {report.displacement_pp_um:.2f} um\n"
        f"  first felt pulse    {first} after the pen touched ({'from standby' if report.standby else 'from cold'})\n"
        f"  pulse               {report.current_ma:.0f} mA for {report.pulse_width_ms:.3f} ms\n"
        f"  peak temperature    {report.peak_temperature_c:.1f} C (limit {spec.max_temperature_c:g} C)"
    )
    return doc, text


def simulate_raw(opt: dict[str, Any]) -> tuple[dict[str, Any], str]:
    """One drive exactly as asked, open loop, on an ideal current source."""
    from ..actuators.sma import build_envelope, simulate_drive
    from ..drive import Drive

    for name, key in (("frequency", "frequency_hz"), ("pulse-width-ms", "pulse_width_ms"), ("current-ma", "current_ma")):
        if opt[key] is None:
            raise TactilizeError(f"--{name}", "give --texture/--image and --speed, or --frequency, --pulse-width-ms and --current-ma")
    _finite("frequency", opt["frequency_hz"])
    _finite("pulse-width-ms", opt["pulse_width_ms"])
    _finite("current-ma", opt["current_ma"])
    duration_s = 5.0 if opt["duration_s"] is None else opt["duration_s"]
    _finite("duration", duration_s)
    if duration_s > 600:
        raise TactilizeError("--duration", f"at most 600 s, got {duration_s}")
    f, width_s, current_a = opt["frequency_hz"], opt["pulse_width_ms"] / 1e3, opt["current_ma"] / 1e3
    if width_s * f >= 1:
        raise TactilizeError("--pulse-width-ms", f"{opt['pulse_width_ms']} ms does not fit in a {1e3 / f:g} ms period")
    spec, _ = _wire_and_circuit(opt)
    if opt["plot_path"]:
        from .plots import plot_option

        plot_option(opt["plot_path"])
    drv = Drive(f, width_s)
    result = simulate_drive(drv, duration_s, spec, current_a=current_a)
    summary = result.summary()
    from ..actuators.sma import Circuit

    env = build_envelope(spec, Circuit.ideal_current(current_a))
    hi = env.max_pulse_width_s(f)
    doc = {
        "wire": spec.name,
        "length_mm": spec.length_m * 1e3,
        "frequency_hz": f,
        "pulse_width_ms": opt["pulse_width_ms"],
        "current_ma": opt["current_ma"],
        "duty_ratio": drv.duty_ratio,
        "duration_s": duration_s,
        "displacement_pp_um": summary["displacement_pp_um"],
        "follows": summary["follows"],
        "mean_temperature_c": summary["mean_temperature_c"],
        "peak_temperature_c": summary["peak_temperature_c"],
        "allowed": env.allows(drv),
        "max_allowed_pulse_width_ms": hi * 1e3,
        "max_temperature_c": spec.max_temperature_c,
        "pulses_followed": summary["pulses_followed"],
        "pulses_in_window": summary["pulses_in_window"],
        "settled_from_s": duration_s * 2 / 3,
        "electrical_j": result.electrical_j,
        "stored_j": result.stored_j,
        "convected_j": result.convected_j,
        "latent_j": result.latent_j,
    }
    if opt["plot_path"]:
        from .plots import plot_simulation

        plot_simulation(result, spec, doc, f, opt["pulse_width_ms"], opt["current_ma"], opt["plot_path"])
        doc["plot"] = opt["plot_path"]
    text = (
        f"{spec.name} wire ({spec.length_m * 1e3:g} mm), {f:g} Hz, {opt['pulse_width_ms']:g} ms, "
        f"{opt['current_ma']:g} mA (duty {drv.duty_ratio * 100:.2f} %), {duration_s:g} s, open loop\n"
        f"  displacement p-p    {doc['displacement_pp_um']:.3f} um (settled, per pulse)\n"
        f"  follows             {'yes' if doc['follows'] else 'no'} ({doc['pulses_followed']}/{doc['pulses_in_window']} pulses)\n"
        f"  mean temperature    {doc['mean_temperature_c']:.2f} C\n"
        f"  peak temperature    {doc['peak_temperature_c']:.2f} C (limit {spec.max_temperature_c:g} C)\n"
        f"  allowed             {'yes' if doc['allowed'] else 'no'} (envelope on this current: width up to {hi * 1e3:.3f} ms)"
    )
    if opt["plot_path"]:
        text = f"wrote {opt['plot_path']}\n{text}"
    return doc, text


def envelope_table(spec: Any, circuit: Any, plot_path: str | None) -> tuple[dict[str, Any], str]:
    """The felt band and the envelope per frequency, as a document and a table."""
    from ..actuators.sma import WireController

    if plot_path:
        from .plots import plot_option

        plot_option(plot_path)
    ctrl = WireController(spec, circuit)
    env = ctrl.envelope
    power = circuit.power_at(spec.resistance_martensite_ohm)
    freqs = (1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 150.0, 200.0, 300.0)
    rows: list[dict[str, Any]] = []
    for f in freqs:
        lo, hi = ctrl.band_j(f)
        rows.append({
            "frequency_hz": f,
            "felt_band_j": [lo, hi],
            "felt_band_width_s": [lo / power, hi / power],
            "max_pulse_energy_j": env.max_pulse_energy_j(f),
            "max_width_s": env.max_pulse_width_s(f),
        })
    doc = {**env.to_dict(freqs), "hold_power_w": ctrl.hold_w, "bands": rows}
    if plot_path:
        from .plots import plot_envelope

        plot_envelope(rows, spec, circuit, plot_path)
        doc["plot"] = plot_path
    c = circuit.describe(spec)
    lines = [
        f"{spec.name} wire ({spec.length_m * 1e3:g} mm) on {circuit.name}: "
        f"{c['current_relaxed_a'] * 1e3:.0f} mA relaxed, {c['current_contracted_a'] * 1e3:.0f} mA contracted, "
        f"worst heat {c['max_power_w'] * 1e3:.0f} mW while on",
        f"  holding heat {ctrl.hold_w * 1e3:.2f} mW; envelope for air up to {env.design_ambient_c:g} C, "
        f"peak {spec.max_temperature_c:g} C",
        "  f [Hz]   felt band [ms at full switch]   envelope: largest width [ms]",
    ]
    for r in rows:
        lo, hi = r["felt_band_width_s"]
        lines.append(f"  {r['frequency_hz']:>6g}   {lo * 1e3:8.3f} .. {hi * 1e3:<8.3f}            {r['max_width_s'] * 1e3:.3f}")
    if plot_path:
        lines.insert(0, f"wrote {plot_path}")
    return doc, "\n".join(lines)
