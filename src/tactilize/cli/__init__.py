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
from typing import TYPE_CHECKING, Any

import click

from ..errors import TactilizeError, check_finite
from ..mapping.profile import DEFAULT_PRESET
from ..encode import dumps
from .materials import choice_of, describe_relief, material_option, materials_cmd, surface_only

if TYPE_CHECKING:  # the wire model loads on the commands that use it
    from ..actuators.sma import Circuit, WireSpec

BAD_INPUT = 2


#: The extra to name when a module comes with several: the one of the command.
_PREFERRED_EXTRA = {"batch": "batch", "experiment": "experiments", "serve": "batch"}


class _Group(click.Group):
    """Turns library errors into one line and exit status 2, never a traceback."""

    def invoke(self, ctx: click.Context) -> Any:
        try:
            return super().invoke(ctx)
        except TactilizeError as exc:
            click.echo(f"tactilize: {exc.source}: {exc.fault}", err=True)
            ctx.exit(BAD_INPUT)
        except click.UsageError as exc:
            # click's own faults (a type, a missing option, an unknown command) print
            # usage, a hint and the error on four lines; the one-line rule holds for them too.
            if exc.__class__.__name__ == "NoArgsIsHelpError":  # a bare group: its help, as asked
                raise
            click.echo(f"tactilize: {' '.join(exc.format_message().split())} (see --help)", err=True)
            ctx.exit(BAD_INPUT)
        except (click.exceptions.Exit, click.exceptions.Abort, click.ClickException):
            raise
        except KeyboardInterrupt:
            click.echo("tactilize: interrupted", err=True)
            ctx.exit(130)
        except BrokenPipeError:
            # The reader went away (`... | head`): not an error.  Point stdout at
            # /dev/null so that the interpreter's final flush cannot fail again.
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            ctx.exit(0)
        except Exception as exc:  # a bug, not bad input: still one line, unless asked
            from ..extras import extra_for, missing

            if isinstance(exc, ModuleNotFoundError) and extra_for(exc.name or "") is not None:
                # An optional module the code imported without tactilize.extras.require:
                # the same one line, naming the command.
                command = ctx.meta.get("tactilize.command", "")
                err = missing(f"tactilize {command}".strip(), exc.name or "", _PREFERRED_EXTRA.get(command.split(" ")[0]))
                click.echo(f"tactilize: {err.source}: {err.fault}", err=True)
                ctx.exit(BAD_INPUT)
            if os.environ.get("TACTILIZE_DEBUG"):
                raise
            click.echo(
                f"tactilize: internal error: {exc.__class__.__name__}: {exc} (set TACTILIZE_DEBUG=1 for a traceback)",
                err=True,
            )
            ctx.exit(1)

    def resolve_command(self, ctx: click.Context, args: list[str]) -> Any:
        # Remember the (sub)command names, e.g. "experiment analyze", for the
        # missing-extra line above.
        name, cmd, rest = super().resolve_command(ctx, args)
        words = [name or ""]
        if isinstance(cmd, click.Group) and rest and rest[0] in cmd.commands:
            words.append(rest[0])
        ctx.meta["tactilize.command"] = " ".join(words)
        return name, cmd, rest


def emit_json(doc: Any) -> None:
    """Print one JSON document (NaN and infinities become null, as JSON has none)."""
    click.echo(dumps(doc))


def _positive(name: str):
    def check(ctx, param, value):
        return value if value is None else check_finite(value, f"--{name}", above=0.0)

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
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document: a list, one object per IMAGE.")
@material_option
@click.option("--plot", "plot_path", default=None,
              help="Draw the paper's Fig. 5 (image, log spectrum with the peak, tile map) to this image file; "
                   "with several IMAGEs one file each, FILE's name plus the image's (fig.png: fig-cloth.png ...).")
def analyze(images: tuple[str, ...], dpi: float | None, width_mm: float | None, as_json: bool,
            material_name: str | None, relief_mm: float | None, plot_path: str | None) -> None:
    """Measure the texture features of IMAGE(s); with --material or --relief-mm, also its relief in metres."""
    from ..features import extract_features
    from ..image import load_image

    if dpi is not None and width_mm is not None:
        raise TactilizeError("--dpi/--width-mm", "give one of them, not both")
    choice = choice_of(material_name, relief_mm)
    if plot_path is not None:
        from .plots import plot_option, plot_paths

        plot_option(plot_path)  # a missing matplotlib or folder is said before any work
        plots = plot_paths(plot_path, images)
    rows = []
    for i, path in enumerate(images):
        img = load_image(path, dpi=dpi, width_mm=width_mm)
        feat = extract_features(img)
        rows.append({"image": path, **img.describe(), **feat.to_dict()})
        if not choice.picture_only:
            from ..surface import surface_model

            rows[-1].update(describe_relief(surface_model(img, **choice.surface_kwargs()), choice))
        if plot_path is not None:
            from ..maps.texturemap import texture_map
            from .plots import plot_spectrum

            plot_spectrum(img, feat, texture_map(img), plots[i])
            rows[-1]["plot"] = plots[i]
    if as_json:
        # Always a list, one object per image in the order given (one image too),
        # so that a script reads the same shape whatever it is given.
        emit_json(rows)
        return
    for row in rows:
        if "plot" in row:
            click.echo(f"wrote {row['plot']}")
        click.echo(
            f"{row['image']}\n"
            f"  size                {row['width_px']} x {row['height_px']} px, {row['width_mm']:.1f} x {row['height_mm']:.1f} mm\n"
            f"  spatial frequency   {row['spatial_frequency_per_m']:.1f} cycles/m (wavelength {row['wavelength_mm']:.3f} mm)\n"
            f"  spectral intensity  {row['spectral_intensity']:.3f}\n"
            f"  modulation depth    {row['modulation_depth']:.3f}   periodicity {row['periodicity']:.3f}\n"
            f"  orientation         {row['orientation_deg']:.1f} deg   anisotropy {row['anisotropy']:.3f}\n"
            f"  contrast            {row['contrast']:.3f}   roughness {row['roughness_per_mm']:.3f} /mm"
        )
        if row.get("relief_scale_m") is not None:
            click.echo(f"  rendered as         {row['rendered_as']}: relief {row['relief_scale_m'] * 1e6:.4g} um per "
                       f"luminance range ({row['relief_source']})")


@main.command()
@click.argument("image")
@click.option("--speed", "speed_mm_s", type=float, required=True, help="Stroking speed [mm/s].")
@click.option("--direction-deg", type=float, default=None, help="Stroke direction [deg], counter-clockwise from +x.")
@click.option("--profile", "profile_name", default=DEFAULT_PRESET, show_default=True, help="Preset name or TOML file.")
@click.option("--dpi", type=float, callback=_positive("dpi"), help="Pixels per inch of the displayed image.")
@click.option("--width-mm", type=float, callback=_positive("width-mm"), help="Displayed width of the image [mm].")
@click.option("--output", "output_spec", default=None, help="Send the drive to: simulated | serial:PATH | audio[:DEVICE].")
@click.option("--hold", "hold_s", type=float, default=None, help="With --output: seconds to keep the drive on [s] (default 1).")
@material_option
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
    material_name: str | None,
    relief_mm: float | None,
    as_json: bool,
) -> None:
    """The pulse drive for IMAGE stroked at a speed; with --output, also run it on
    an actuator for --hold seconds (exit 0 only when the output acknowledged)."""
    from ..features import extract_features
    from ..image import load_image
    from ..mapping import Profile

    check_finite(speed_mm_s, "--speed", minimum=0.0, unit="mm/s")
    if hold_s is not None and (not math.isfinite(hold_s) or hold_s < 0 or output_spec is None):
        raise TactilizeError("--hold", "needs --output and a number of seconds >= 0")
    profile = Profile.resolve(profile_name)
    choice = choice_of(material_name, relief_mm)
    surface_only(choice, profile)
    img = load_image(image, dpi=dpi, width_mm=width_mm)
    feat = extract_features(img)
    direction = math.radians(direction_deg) if direction_deg is not None else None
    from ..surface.rendering import rendering_for

    rendering = rendering_for(profile, image=img, **choice.surface_kwargs())
    drv = rendering.steady_drive(feat, speed_mm_s / 1e3, direction)
    doc = {
        "image": image,
        "profile": profile.name,
        "rendering": rendering.name,
        **({} if choice.picture_only else describe_relief(rendering.surface, choice)),
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
        f"{image} at {speed_mm_s:g} mm/s, profile {profile.name} ({rendering.name} rendering"
        f"{'' if choice.picture_only else ', rendered as ' + choice.label()})\n"
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
@click.option("--profile", "profile_name", default=DEFAULT_PRESET, show_default=True, help="Preset name or TOML file.")
@click.option("--dpi", type=float, callback=_positive("dpi"), help="Pixels per inch where the manifest says nothing.")
@click.option("--analysis-dpi", type=float, callback=_positive("analysis-dpi"), help="Lowest resolution the analysis may use; lets JPEGs decode at 1/2..1/8 size.")
@click.option("--full-map", is_flag=True, help="Measure every texture-map tile whole (default: its centred half when that holds two periods).")
@click.option("--workers", type=int, default=None, help="Local processes (default: all cores; 1 = in this process).")
@click.option("--scheduler", default=None, help="Dask scheduler address (tcp://HOST:PORT): run on that cluster.")
@click.option("--retry-failed", is_flag=True, help="Analyse again the images whose earlier row is an error.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON summary document at the end.")
@material_option
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
    material_name: str | None,
    relief_mm: float | None,
) -> None:
    """Analyse every image of SOURCE (folder, glob, or CSV/JSONL manifest) into a catalog; resumes.

    --material and --relief-mm: what every picture is rendered as where its manifest row
    has no `material` or `relief_mm` of its own."""
    from ..catalog import TerminalProgress, run_batch
    from ..image import METRES_PER_INCH
    from ..mapping import Profile

    if workers is not None and workers < 1:
        raise TactilizeError("--workers", f"must be at least 1, got {workers}")
    choice = choice_of(material_name, relief_mm)
    profile = Profile.resolve(profile_name)
    surface_only(choice, profile)
    bar = TerminalProgress(sys.stderr)
    try:
        summary = run_batch(
            source,
            out,
            profile=profile,
            dpi=dpi,
            analysis_pitch_m=METRES_PER_INCH / analysis_dpi if analysis_dpi else None,
            full_map=full_map,
            material=choice.name,
            relief_rms_m=choice.relief_rms_m,
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
@click.option("--profile", "profile_name", default=None, help="Preset name or TOML file [default: surface].")
@click.option("--open/--no-open", "open_browser", default=None, help="Open the page in a browser [default: when a display exists].")
@click.option("--catalog", "catalog_path", default=None, help="Also serve this catalog (Parquet folder or SQLAlchemy URL) at /api/catalog, and its shop site at /shop/.")
@click.option("--site", "site_dir", default=None, help="Also serve a site written by `tactilize site` at /shop/ (instead of the catalog's own).")
@click.option("--max-sockets", type=click.IntRange(1, 10_000), default=32, show_default=True,
              help="Pages (WebSockets) connected at once, at most; one more is refused with 503.")
@click.option("--lan", is_flag=True, help="Serve on this machine's network address for a phone: prints the address and a QR code.")
@click.option("--https", "use_https", is_flag=True, help="HTTPS with a self-signed certificate kept in the user data dir (audio and raw pen updates on a phone need it).")
@material_option
def serve(host: str, port: int, output_spec: str, profile_name: str | None, open_browser: bool | None, catalog_path: str | None,
          site_dir: str | None, max_sockets: int, lan: bool, use_https: bool, material_name: str | None = None,
          relief_mm: float | None = None) -> None:
    """Serve the tactile pen page: textures, pen stroke, live drive, simulated wire.

    --material and --relief-mm: what the built-in pictures and uploads are rendered as (the
    page's picker may render a picture as another material)."""
    from ..web.serve import serve as run

    choice = choice_of(material_name, relief_mm)

    routers = []
    if catalog_path is not None:
        from ..catalog.api import catalog_router

        routers.append(catalog_router(catalog_path))  # a bad catalog fails here, before the socket opens
        if site_dir is None:
            from ..site.from_catalog import catalog_site

            built = catalog_site(catalog_path)
            site_dir = str(built.folder)
            if built.note(catalog_path):
                click.echo(f"tactilize: {built.note(catalog_path)}", err=True)
    if site_dir is not None:
        from ..site.routes import site_router

        routers.append(site_router(site_dir))
    run(host, port, output_spec, profile_name, open_browser, extra_routers=routers, echo=click.echo,
        warn=lambda s: click.echo(s, err=True), max_sockets=max_sockets, lan=lan, https=use_https, material=choice)


# ----------------------------------------------------------------- simulate / envelope / export


def _wire_option(wire: str, length_mm: float | None):
    """The wire named by ``--wire`` (and ``--length-mm``), errors naming the option."""
    from ..actuators.sma import WireSpec

    if length_mm is not None:
        check_finite(length_mm, "--length-mm", above=0.0, unit="mm")
    try:
        return WireSpec.preset(wire, length_m=None if length_mm is None else length_mm / 1e3)
    except TactilizeError as exc:
        raise TactilizeError(f"--wire {wire}", exc.fault) from None


def _circuit_option(circuit: str, spec: WireSpec) -> Circuit:
    """The circuit named by ``--circuit`` for a wire, errors naming the option."""
    from ..actuators.sma import Circuit

    try:
        return Circuit.preset(circuit, spec)
    except TactilizeError as exc:
        raise TactilizeError(f"--circuit {circuit}", exc.fault) from None


_WIRE_HELP = "Wire preset: 50um, 75um (the paper's) or 100um."
_CIRCUIT_HELP = "Driver circuit: aa-resistor (default), usb-resistor, aa-sink, aa-direct (docs/signals-and-wire.md)."


@main.command("simulate")
@click.option("--texture", "texture_id", default=None, help="A built-in texture to stroke (see `tactilize serve`).")
@click.option("--image", "image_path", default=None, help="Or an image file to stroke.")
@click.option("--speed", "speed_mm_s", type=float, default=None, help="Steady stroking speed [mm/s].")
@click.option("--direction", "direction_deg", type=float, default=None, help="Stroke direction [deg, y up].")
@click.option("--profile", "profile_name", default=DEFAULT_PRESET, show_default=True, help="Preset name or TOML file.")
@click.option("--standby/--no-standby", default=True, show_default=True,
              help="The wire waits in standby (or cold and off) when the pen touches.")
@click.option("--open-loop", is_flag=True, help="The controller trusts the nominal circuit and air.")
@click.option("--frequency", "frequency_hz", type=float, default=None, help="Raw mode: pulse frequency [Hz].")
@click.option("--pulse-width-ms", type=float, default=None, help="Raw mode: pulse width [ms].")
@click.option("--current-ma", type=float, default=None, help="Raw mode: an ideal current source [mA].")
@click.option("--duration", "duration_s", type=float, default=None, help="Simulated time [s] (1.5 s / 5 s raw).")
@click.option("--wire", default="75um", show_default=True, help=_WIRE_HELP)
@click.option("--circuit", default="aa-resistor", show_default=True, help=_CIRCUIT_HELP)
@click.option("--length-mm", type=float, default=None, help="Wire length [mm] (default 3).")
@click.option("--dpi", type=float, callback=_positive("dpi"), help="Pixels per inch of the displayed image.")
@click.option("--width-mm", type=float, callback=_positive("width-mm"), help="Displayed width of the image [mm].")
@click.option("--plot", "plot_path", default=None, help="Raw mode: draw temperature, martensite and displacement.")
@material_option
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
def simulate_cmd(**opt: Any) -> None:
    """What the finger gets: a steady stroke on a texture through the simulated wire.

    With --texture or --image and --speed: the pen's whole path (profile,
    operating-point controller, standby, envelope) for a steady stroke.  With
    --frequency, --pulse-width-ms and --current-ma instead: one drive exactly as
    asked, open loop, on an ideal current source (no controller, no envelope).
    """
    from .simulate import simulate_raw, simulate_stroke

    if opt["texture_id"] is not None or opt["image_path"] is not None:
        doc, text = simulate_stroke(opt)
    else:
        doc, text = simulate_raw(opt)
    if opt["as_json"]:
        emit_json(doc)
        return
    click.echo(text)


@main.command("envelope")
@click.option("--wire", default="75um", show_default=True, help=_WIRE_HELP)
@click.option("--circuit", default="aa-resistor", show_default=True, help=_CIRCUIT_HELP)
@click.option("--length-mm", type=float, default=None, help="Wire length [mm] (default 3).")
@click.option("--plot", "plot_path", default=None, help="Draw the felt band and the envelope to this image file.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
def envelope_cmd(wire: str, circuit: str, length_mm: float | None, plot_path: str | None, as_json: bool) -> None:
    """The wire's felt band and safety envelope on a circuit, per pulse frequency."""
    from .simulate import envelope_table

    spec = _wire_option(wire, length_mm)
    doc, text = envelope_table(spec, _circuit_option(circuit, spec), plot_path)
    if as_json:
        emit_json(doc)
        return
    click.echo(text)


@main.command("export")
@click.argument("image")
@click.option("--stroke", "stroke_path", default=None, help="A recorded stroke: CSV or JSON of t_s, x_mm, y_mm[, pressure].")
@click.option("--speed", "speed_mm_s", type=float, default=None, help="Or a synthetic steady stroke at this speed [mm/s].")
@click.option("--duration", "duration_s", type=float, default=2.0, show_default=True, help="Length of a synthetic stroke [s].")
@click.option("--direction", "direction_deg", type=float, default=0.0, show_default=True, help="Direction of a synthetic stroke [deg, y up].")
@click.option("--format", "fmt", type=str, required=True, help="wav | csv | json | log | ahap | android | hjif | haptic")
@click.option("--drive", "drive_kind", type=click.Choice(["profile", "wire"]), default="profile", show_default=True,
              help="The profile's drive (for phones, players, voice coils) or what the simulated SMA wire applied.")
@click.option("--profile", "profile_name", default=DEFAULT_PRESET, show_default=True, help="Preset name or TOML file.")
@click.option("--dpi", type=float, callback=_positive("dpi"), help="Pixels per inch of the displayed image.")
@click.option("--width-mm", type=float, callback=_positive("width-mm"), help="Displayed width of the image [mm].")
@click.option("-o", "--output", "out_path", required=True, help="File to write.")
@material_option
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document describing what was written.")
def export_cmd(**opt: Any) -> None:
    """Write the drive of a stroke on IMAGE as a file (WAV, CSV, JSON, drive log, AHAP, Android, HJIF, .haptic).

    The stroke (--stroke FILE, or --speed for a synthetic one) runs through the
    pen server's tracker, texture map, profile and simulated wire.
    """
    from .export import export_stroke

    doc, text = export_stroke(opt)
    if opt["as_json"]:
        emit_json(doc)
        return
    click.echo(text)


# ----------------------------------------------------------------- experiment (experiments/)

from ..experiments.cli import experiment as _experiment  # noqa: E402  (click only; the package loads lazily)

main.add_command(_experiment)

from .profile import profile as _profile  # noqa: E402  (click only)

main.add_command(_profile)

main.add_command(materials_cmd)

from .site import site as _site  # noqa: E402  (click only; the builder loads when it runs)

main.add_command(_site)
