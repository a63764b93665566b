"""The command line: parse, call the library, print.  Nothing else lives here.

Every command that reports takes ``--json`` and then prints exactly one JSON
document on stdout.  Bad input (any :class:`~tactilize.errors.TactilizeError`)
prints one line on stderr naming the input and the fault and exits with status 2.

The work behind a few commands lives beside this module: :mod:`.outputs`
(``drive --output``, ``controller-emulator``) and :mod:`.plots` (``--plot``).
"""

from __future__ import annotations

import math
import os
import sys
from typing import Any

import click

from ..errors import TactilizeError
from ..web.encode import dumps

BAD_INPUT = 2


class _Group(click.Group):
    """Turns library errors into one line and exit status 2, never a traceback."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except TactilizeError as exc:
            click.echo(f"tactilize: {exc.source}: {exc.fault}", err=True)
            ctx.exit(BAD_INPUT)
        except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException):
            raise
        except KeyboardInterrupt:
            click.echo("tactilize: interrupted", err=True)
            ctx.exit(130)
        except Exception as exc:  # a bug, not bad input: still one line, unless asked
            if os.environ.get("TACTILIZE_DEBUG"):
                raise
            click.echo(
                f"tactilize: internal error: {exc.__class__.__name__}: {exc} (set TACTILIZE_DEBUG=1 for a traceback)",
                err=True,
            )
            ctx.exit(1)


def emit_json(doc: Any) -> None:
    """Print one JSON document (NaN and infinities become null, as JSON has none)."""
    click.echo(dumps(doc))


def _positive(name: str):
    def check(ctx, param, value):
        if value is not None and (not math.isfinite(value) or value <= 0):
            raise TactilizeError(f"--{name}", f"must be a positive number, got {value}")
        return value

    return check


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="tactilize")
def main() -> None:
    """tactilize: turn pictures of surfaces into touch."""


# ----------------------------------------------------------------- analyze / drive


@main.command()
@click.argument("images", nargs=-1, required=True)
@click.option("--dpi", type=float, callback=_positive("dpi"), help="Pixels per inch of the displayed image.")
@click.option("--width-mm", type=float, callback=_positive("width-mm"), help="Displayed width of the image [mm].")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
def analyze(images: tuple[str, ...], dpi: float | None, width_mm: float | None, as_json: bool) -> None:
    """Measure the texture features of IMAGE(s)."""
    from ..features import extract_features
    from ..image import load_image

    if dpi is not None and width_mm is not None:
        raise TactilizeError("--dpi/--width-mm", "give one of them, not both")
    rows = []
    for path in images:
        img = load_image(path, dpi=dpi, width_mm=width_mm)
        feat = extract_features(img)
        rows.append({"image": path, **img.describe(), **feat.to_dict()})
    if as_json:
        emit_json(rows[0] if len(rows) == 1 else rows)
        return
    for row in rows:
        click.echo(
            f"{row['image']}\n"
            f"  size                {row['width_px']} x {row['height_px']} px, {row['width_mm']:.1f} x {row['height_mm']:.1f} mm\n"
            f"  spatial frequency   {row['spatial_frequency_per_m']:.1f} cycles/m (wavelength {row['wavelength_mm']:.3f} mm)\n"
            f"  spectral intensity  {row['spectral_intensity']:.3f}\n"
            f"  modulation depth    {row['modulation_depth']:.3f}   periodicity {row['periodicity']:.3f}\n"
            f"  orientation         {row['orientation_deg']:.1f} deg   anisotropy {row['anisotropy']:.3f}\n"
            f"  contrast            {row['contrast']:.3f}   roughness {row['roughness_per_mm']:.3f} /mm"
        )


@main.command()
@click.argument("image")
@click.option("--speed", "speed_mm_s", type=float, required=True, help="Stroking speed [mm/s].")
@click.option("--direction-deg", type=float, default=None, help="Stroke direction [deg], counter-clockwise from +x.")
@click.option("--profile", "profile_name", default="paper", show_default=True, help="Preset name or TOML file.")
@click.option("--dpi", type=float, callback=_positive("dpi"), help="Pixels per inch of the displayed image.")
@click.option("--width-mm", type=float, callback=_positive("width-mm"), help="Displayed width of the image [mm].")
@click.option("--output", "output_spec", default=None, help="Send the drive to: simulated | serial:PATH | audio[:DEVICE].")
@click.option("--hold", "hold_s", type=float, default=None, help="With --output: seconds to keep the drive on [s] (default 1).")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
def drive(
    image: str,
    speed_mm_s: float,
    direction_deg: float | None,
    profile_name: str,
    dpi: float | None,
    width_mm: float | None,
    output_spec: str | None,
    hold_s: float | None,
    as_json: bool,
) -> None:
    """The pulse drive for IMAGE stroked at a speed; with --output, also run it on
    an actuator for --hold seconds (exit 0 only when the output acknowledged)."""
    from ..features import extract_features
    from ..image import load_image
    from ..mapping import Profile

    if not math.isfinite(speed_mm_s) or speed_mm_s < 0:
        raise TactilizeError("--speed", f"must be a number >= 0 mm/s, got {speed_mm_s}")
    if hold_s is not None and (not math.isfinite(hold_s) or hold_s < 0 or output_spec is None):
        raise TactilizeError("--hold", "needs --output and a number of seconds >= 0")
    profile = Profile.resolve(profile_name)
    img = load_image(image, dpi=dpi, width_mm=width_mm)
    feat = extract_features(img)
    direction = math.radians(direction_deg) if direction_deg is not None else None
    drv = profile.drive(feat, speed_m_s=speed_mm_s / 1e3, direction_rad=direction)
    doc = {
        "image": image,
        "profile": profile.name,
        "speed_mm_s": speed_mm_s,
        "spatial_frequency_per_m": feat.spatial_frequency_per_m,
        "spectral_intensity": feat.spectral_intensity,
        "orientation_deg": feat.orientation_deg,
        **drv.to_dict(),
    }
    if output_spec is not None:
        from .outputs import hold_drive

        doc["output"] = hold_drive(output_spec, drv, 1.0 if hold_s is None else hold_s)
    if as_json:
        emit_json(doc)
        return
    clamp = ", ".join(drv.clamped) if drv.clamped else "none"
    click.echo(
        f"{image} at {speed_mm_s:g} mm/s, profile {profile.name}\n"
        f"  pulse frequency  {drv.pulse_frequency_hz:.1f} Hz\n"
        f"  pulse width      {drv.pulse_width_s * 1e3:.3f} ms\n"
        f"  duty ratio       {drv.duty_ratio * 100:.2f} %\n"
        f"  amplitude        {drv.amplitude:.2f}\n"
        f"  clamped by       {clamp}"
    )
    if output_spec is not None:
        sent = doc["output"]["applied"][0]
        click.echo(
            f"  output           {output_spec}: {sent['pulse_frequency_hz']:.1f} Hz, {sent['pulse_width_ms']:.3f} ms,"
            f" held {doc['output']['held_s']:.2f} s, acknowledged"
        )


@main.command("controller-emulator")
@click.option("--link", default=None, help="Also make a symlink at this path to the device (stable across restarts).")
def controller_emulator(link: str | None) -> None:
    """Run the tactile controller firmware on a pseudo-terminal.

    Prints the device path to open as the first line, then one JSON line per
    output change.  Runs until SIGINT or SIGTERM.
    """
    from .outputs import run_controller_emulator

    run_controller_emulator(link)


# ----------------------------------------------------------------- batch (catalog.py)


@main.command()
@click.argument("source")
@click.option("--out", "out", required=True, help="Parquet catalog folder, or an SQLAlchemy URL (sqlite:///shop.db).")
@click.option("--profile", "profile_name", default="paper", show_default=True, help="Preset name or TOML file.")
@click.option("--dpi", type=float, callback=_positive("dpi"), help="Pixels per inch where the manifest says nothing.")
@click.option("--analysis-dpi", type=float, callback=_positive("analysis-dpi"), help="Lowest resolution the analysis may use; lets JPEGs decode at 1/2..1/8 size.")
@click.option("--full-map", is_flag=True, help="Measure every texture-map tile whole (default: its centred half when that holds two periods).")
@click.option("--workers", type=int, default=None, help="Local processes (default: all cores; 1 = in this process).")
@click.option("--scheduler", default=None, help="Dask scheduler address (tcp://HOST:PORT): run on that cluster.")
@click.option("--retry-failed", is_flag=True, help="Analyse again the images whose earlier row is an error.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON summary document at the end.")
def batch(
    source: str,
    out: str,
    profile_name: str,
    dpi: float | None,
    analysis_dpi: float | None,
    full_map: bool,
    workers: int | None,
    scheduler: str | None,
    retry_failed: bool,
    as_json: bool,
) -> None:
    """Analyse every image of SOURCE (folder, glob, or CSV/JSONL manifest) into a catalog; resumes."""
    from ..catalog import TerminalProgress, run_batch
    from ..image import METRES_PER_INCH

    if workers is not None and workers < 1:
        raise TactilizeError("--workers", f"must be at least 1, got {workers}")
    bar = TerminalProgress(sys.stderr)
    try:
        summary = run_batch(
            source,
            out,
            profile=profile_name,
            dpi=dpi,
            analysis_pitch_m=METRES_PER_INCH / analysis_dpi if analysis_dpi else None,
            full_map=full_map,
            workers=workers,
            scheduler=scheduler,
            retry_failed=retry_failed,
            progress=bar,
        )
    finally:
        bar.close()
    if as_json:
        emit_json(summary.to_dict())
        return
    click.echo(
        f"{summary.out}: {summary.ok} ok, {summary.failed} failed, {summary.skipped} already done "
        f"(of {summary.total}) in {summary.seconds:.1f} s, {summary.images_per_second:.1f} images/s"
    )


# ----------------------------------------------------------------- serve (web/)


@main.command()
@click.option("--host", default="127.0.0.1", show_default=True, help="Address to bind; anything but loopback must be asked for.")
@click.option("--port", type=click.IntRange(0, 65535), default=8765, show_default=True, help="TCP port (0: any free port).")
@click.option("--output", "output_spec", default="simulated", show_default=True, help="simulated | serial:PORT | audio[:DEVICE]")
@click.option("--profile", "profile_name", default=None, help="Preset name or TOML file [default: paper].")
@click.option("--open/--no-open", "open_browser", default=None, help="Open the page in a browser [default: when a display exists].")
@click.option("--catalog", "catalog_path", default=None, help="Also serve this catalog (Parquet folder or SQLAlchemy URL) at /api/catalog.")
def serve(host: str, port: int, output_spec: str, profile_name: str | None, open_browser: bool | None, catalog_path: str | None) -> None:
    """Serve the tactile pen page: textures, pen stroke, live drive, simulated wire."""
    from ..web.serve import serve as run

    routers = []
    if catalog_path is not None:
        from ..catalog_api import catalog_router

        routers.append(catalog_router(catalog_path))  # a bad catalog fails here, before the socket opens
    run(host, port, output_spec, profile_name, open_browser, extra_routers=routers, echo=click.echo, warn=lambda s: click.echo(s, err=True))


# ----------------------------------------------------------------- simulate / envelope / export


def _wire_option(wire: str, length_mm: float | None):
    """The wire named by ``--wire`` (and ``--length-mm``), errors naming the option."""
    from ..actuators.sma import WireSpec

    try:
        return WireSpec.preset(wire, length_m=None if length_mm is None else length_mm / 1e3)
    except TactilizeError as exc:
        raise TactilizeError(f"--wire {wire}", exc.fault) from None


@main.command("simulate")
@click.option("--frequency", "frequency_hz", type=float, required=True, help="Pulse frequency [Hz].")
@click.option("--pulse-width-ms", type=float, required=True, help="Pulse width [ms].")
@click.option("--current-ma", type=float, required=True, help="Peak pulse current into the relaxed wire [mA].")
@click.option("--duration", "duration_s", type=float, default=5.0, show_default=True, help="Simulated time [s].")
@click.option("--wire", default="75um", show_default=True, help="Wire preset: 50um, 75um (the paper's) or 100um.")
@click.option("--length-mm", type=float, default=None, help="Wire length [mm] (default 3).")
@click.option("--plot", "plot_path", default=None, help="Draw temperature, martensite and displacement to this image file.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
def simulate_cmd(
    frequency_hz: float,
    pulse_width_ms: float,
    current_ma: float,
    duration_s: float,
    wire: str,
    length_mm: float | None,
    plot_path: str | None,
    as_json: bool,
) -> None:
    """Simulate the SMA wire under a pulse drive, exactly as asked (no envelope)."""
    from ..actuators.sma import build_envelope, simulate_drive
    from ..mapping import Drive

    for name, value in (("frequency", frequency_hz), ("pulse-width-ms", pulse_width_ms), ("duration", duration_s)):
        if not math.isfinite(value) or value <= 0:
            raise TactilizeError(f"--{name}", f"must be a positive number, got {value}")
    if not math.isfinite(current_ma) or current_ma < 0:
        raise TactilizeError("--current-ma", f"must be a number >= 0 mA, got {current_ma}")
    if duration_s > 600:
        raise TactilizeError("--duration", f"at most 600 s, got {duration_s}")
    if length_mm is not None and (not math.isfinite(length_mm) or length_mm <= 0):
        raise TactilizeError("--length-mm", f"must be a positive number, got {length_mm}")
    width_s = pulse_width_ms / 1e3
    if width_s * frequency_hz >= 1:
        raise TactilizeError("--pulse-width-ms", f"{pulse_width_ms} ms does not fit in a {1e3 / frequency_hz:g} ms period")
    spec = _wire_option(wire, length_mm)
    current_a = current_ma / 1e3
    drv = Drive(frequency_hz, width_s)
    result = simulate_drive(drv, duration_s, spec, current_a=current_a)
    summary = result.summary()
    env = build_envelope(spec)
    lo, hi = env.follow_band_s(frequency_hz, current_a)
    doc = {
        "wire": spec.name,
        "length_mm": spec.length_m * 1e3,
        "frequency_hz": frequency_hz,
        "pulse_width_ms": pulse_width_ms,
        "current_ma": current_ma,
        "duty_ratio": drv.duty_ratio,
        "duration_s": duration_s,
        "displacement_pp_um": summary["displacement_pp_um"],
        "follows": summary["follows"],
        "mean_temperature_c": summary["mean_temperature_c"],
        "peak_temperature_c": summary["peak_temperature_c"],
        "allowed": env.allows(drv, current_a=current_a),
        "max_allowed_pulse_width_ms": hi * 1e3,
        "follow_onset_pulse_width_ms": lo * 1e3,
        "max_temperature_c": spec.max_temperature_c,
        "pulses_followed": summary["pulses_followed"],
        "pulses_in_window": summary["pulses_in_window"],
        "settled_from_s": duration_s * 2 / 3,
        "electrical_j": result.electrical_j,
        "stored_j": result.stored_j,
        "convected_j": result.convected_j,
        "latent_j": result.latent_j,
    }
    if plot_path:
        from .plots import plot_simulation

        plot_simulation(result, spec, doc, frequency_hz, pulse_width_ms, current_ma, plot_path)
        doc["plot"] = plot_path
    if as_json:
        emit_json(doc)
        return
    click.echo(
        f"{spec.name} wire ({spec.length_m * 1e3:g} mm), {frequency_hz:g} Hz, {pulse_width_ms:g} ms, {current_ma:g} mA "
        f"(duty {drv.duty_ratio * 100:.2f} %), {duration_s:g} s\n"
        f"  displacement p-p    {doc['displacement_pp_um']:.3f} um (settled, per pulse)\n"
        f"  follows             {'yes' if doc['follows'] else 'no'} ({doc['pulses_followed']}/{doc['pulses_in_window']} pulses)\n"
        f"  mean temperature    {doc['mean_temperature_c']:.2f} C\n"
        f"  peak temperature    {doc['peak_temperature_c']:.2f} C (limit {spec.max_temperature_c:g} C)\n"
        f"  allowed             {'yes' if doc['allowed'] else 'no'} (envelope: width up to {hi * 1e3:.3f} ms)"
    )


@main.command("envelope")
@click.option("--wire", default="75um", show_default=True, help="Wire preset: 50um, 75um (the paper's) or 100um.")
@click.option("--length-mm", type=float, default=None, help="Wire length [mm] (default 3).")
@click.option("--plot", "plot_path", default=None, help="Draw the safe region to this image file.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
def envelope_cmd(wire: str, length_mm: float | None, plot_path: str | None, as_json: bool) -> None:
    """The wire's safety envelope: the largest pulse width per frequency and current."""
    from ..actuators.sma import build_envelope

    if length_mm is not None and (not math.isfinite(length_mm) or length_mm <= 0):
        raise TactilizeError("--length-mm", f"must be a positive number, got {length_mm}")
    spec = _wire_option(wire, length_mm)
    env = build_envelope(spec)
    doc = env.to_dict()
    if plot_path:
        from .plots import plot_envelope

        plot_envelope(env, spec, plot_path)
        doc["plot"] = plot_path
    if as_json:
        emit_json(doc)
        return
    head = "  f [Hz] " + "".join(f"{c * 1e3:>20.0f} mA" for c in env.currents_a)
    lines = [f"{spec.name} wire ({spec.length_m * 1e3:g} mm): vibrating band .. largest allowed pulse width [ms]", head]
    for f, hi_row, lo_row in zip(env.frequencies_hz, env.max_width_s, env.min_follow_width_s):
        cells = "".join(
            f"{(f'{lo * 1e3:.3f}' if math.isfinite(lo) else '-'):>11} .. {hi * 1e3:<8.3f}" for hi, lo in zip(hi_row, lo_row)
        )
        lines.append(f"  {f:>6g} " + cells)
    click.echo("\n".join(lines))


@main.command("export")
@click.argument("image")
@click.option("--speed", "speed_mm_s", type=float, required=True, help="Stroking speed [mm/s].")
@click.option("--format", "fmt", type=str, required=True, help="wav | csv | json | ahap | android")
@click.option("--duration", "duration_s", type=float, default=2.0, show_default=True, help="Length [s].")
@click.option("--profile", "profile_name", default="paper", show_default=True, help="Preset name or TOML file.")
@click.option("--dpi", type=float, callback=_positive("dpi"), help="Pixels per inch of the displayed image.")
@click.option("--width-mm", type=float, callback=_positive("width-mm"), help="Displayed width of the image [mm].")
@click.option("-o", "--output", "out_path", required=True, help="File to write.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document describing what was written.")
def export_cmd(
    image: str,
    speed_mm_s: float,
    fmt: str,
    duration_s: float,
    profile_name: str,
    dpi: float | None,
    width_mm: float | None,
    out_path: str,
    as_json: bool,
) -> None:
    """Write the drive for IMAGE stroked at a speed as a file (WAV, CSV, JSON, AHAP, Android)."""
    from ..export import FORMATS, export
    from ..features import extract_features
    from ..image import load_image
    from ..mapping import Profile

    if fmt.lower() not in FORMATS:
        raise TactilizeError("--format", f"unknown format {fmt!r} (use one of: {', '.join(FORMATS)})")
    if not math.isfinite(speed_mm_s) or speed_mm_s < 0:
        raise TactilizeError("--speed", f"must be a number >= 0 mm/s, got {speed_mm_s}")
    if not math.isfinite(duration_s) or duration_s <= 0 or duration_s > 600:
        raise TactilizeError("--duration", f"must be a number in (0, 600] s, got {duration_s}")
    if dpi is not None and width_mm is not None:
        raise TactilizeError("--dpi/--width-mm", "give one of them, not both")
    profile = Profile.resolve(profile_name)
    img = load_image(image, dpi=dpi, width_mm=width_mm)
    feat = extract_features(img)
    drv = profile.drive(feat, speed_m_s=speed_mm_s / 1e3)
    extra = {
        "image": image,
        "profile": profile.name,
        "speed_mm_s": speed_mm_s,
        "spatial_frequency_per_m": feat.spatial_frequency_per_m,
        "spectral_intensity": feat.spectral_intensity,
    }
    path = export(drv, out_path, fmt.lower(), duration_s, **extra)
    doc = {"path": str(path), "format": fmt.lower(), "duration_s": duration_s, **extra, **drv.to_dict()}
    if as_json:
        emit_json(doc)
        return
    click.echo(
        f"wrote {path} ({fmt.lower()}, {duration_s:g} s): {drv.pulse_frequency_hz:.1f} Hz, "
        f"{drv.pulse_width_s * 1e3:.3f} ms, amplitude {drv.amplitude:.2f}"
    )


# ----------------------------------------------------------------- experiment (experiments/)

from ..experiments.cli import experiment as _experiment  # noqa: E402  (click only; the package loads lazily)

main.add_command(_experiment)
