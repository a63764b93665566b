"""``tactilize profile report``: a profile over textures and speeds, as a designer reads it."""

from __future__ import annotations

import math
from typing import Any

import click

from ..errors import TactilizeError
from ..mapping.profile import DEFAULT_PRESET
from .materials import choice_of, material_option, surface_only

__all__ = ["profile"]


@click.group()
def profile() -> None:
    """Look at a profile before a participant or a customer does."""


@profile.command("report")
@click.option("--profile", "profile_name", default=DEFAULT_PRESET, show_default=True, help="Preset name or TOML file.")
@click.option("--image", "images", multiple=True, help="An image to include instead of the built-in textures (repeat).")
@click.option("--dpi", type=float, default=None, help="Pixels per inch of the given images.")
@click.option("--width-mm", type=float, default=None, help="Displayed width of the given images [mm].")
@click.option("--no-wire", is_flag=True, help="Skip playing every drive on the simulated wire.")
@click.option("--plot", "plot_path", default=None, help="Draw frequency against speed per texture to this file.")
@click.option("--audio", is_flag=True, help="Also the voice coil's signal: the spectrum of the tip's acceleration.")
@click.option("--serial", is_flag=True,
              help="Also the serial link: each stroke played to the controller firmware on a virtual board, in "
                   "simulated time (repeatable; about a second a texture and speed).")
@click.option("--circuit", default="aa-resistor", show_default=True,
              help="The board's circuit for --serial (its stored limits and the host's envelope).")
@material_option
@click.option("--json", "as_json", is_flag=True, help="Print one JSON document.")
def report_cmd(profile_name: str, images: tuple[str, ...], dpi: float | None, width_mm: float | None,
               no_wire: bool, plot_path: str | None, as_json: bool, audio: bool = False, serial: bool = False,
               circuit: str = "aa-resistor", material_name: str | None = None, relief_mm: float | None = None) -> None:
    """The drive each texture gets at 10 .. 160 mm/s, whether the wire follows, and the pairs
    closer than one JND at equal speed.  Every rendering is judged by what it gives a straight
    stroke: pulse rate, interval CV and strength (a steady rendering's: its law's drive).

    --serial plays each stroke over the serial protocol to the controller firmware running on a
    virtual board in simulated time (not the real-time emulator: the figures are the same every
    run): pulses per second that reached the pin, timing error of the pin's pulses against the
    rendered events, and pulses the board's heat estimate shortened or skipped.

    --material and --relief-mm render every picture (the built-in ones too) as that material
    and relief: a surface rendering only."""
    from . import emit_json
    from ..mapping import Profile
    from ..report import FREQUENCY_JND, SPEEDS_MM_S, profile_report

    prof = Profile.resolve(profile_name)
    choice = choice_of(material_name, relief_mm)
    surface_only(choice, prof)
    material = None if choice.picture_only else choice
    if plot_path:
        from .plots import plot_option

        plot_option(plot_path)  # before the minutes of work, not after
    if serial:
        from . import _circuit_option
        from ..actuators.sma import WireSpec

        circuit = _circuit_option(circuit, WireSpec.resolve(None)).name
    pictures = None
    if images:
        from ..image import load_image

        if dpi is not None and width_mm is not None:
            raise TactilizeError("--dpi/--width-mm", "give one of them, not both")
        pictures = {path: load_image(path, dpi=dpi, width_mm=width_mm) for path in images}
    # The features of each picture are extracted by a rendering that reads them (a steady one).
    rep = profile_report(prof, simulate_wire=not no_wire, images=pictures, material=material)
    doc = rep.to_dict()
    if material is not None:
        doc.update(choice.to_dict())
    if plot_path:
        from .plots import plot_profile_report

        plot_profile_report(rep, plot_path, jnd=FREQUENCY_JND)
        doc["plot"] = plot_path
    if audio:
        from ..report import audio_report

        doc["audio"] = audio_report(prof, pictures, material=material)
    if serial:
        from ..serial_report import serial_report

        doc["serial"] = serial_report(prof, pictures, SPEEDS_MM_S, circuit=circuit, material=material)
    if as_json:
        emit_json(doc)
        return
    if plot_path:
        click.echo(f"wrote {plot_path}")
    if material is not None:
        click.echo(f"rendered as {choice.label()}")
    click.echo(_table(rep, SPEEDS_MM_S))
    if audio:
        click.echo(_audio_table(doc["audio"], SPEEDS_MM_S))
    if serial:
        click.echo(_serial_table(doc["serial"], SPEEDS_MM_S, circuit))


def _table(rep: Any, speeds: tuple[float, ...]) -> str:
    names = list(dict.fromkeys(r["texture"] for r in rep.rows))
    width = max(10, *(len(n) for n in names))
    lines = [f"profile {rep.profile}: pulse rate [1/s] a straight stroke produces per texture and speed "
             "(* = the wire does not follow)",
             f"  {'texture':{width}}" + "".join(f"{v:>9g}" for v in speeds) + "   interval CV, strength (mean over speeds)"]
    for n in names:
        rows = [r for r in rep.rows if r["texture"] == n]
        cells = "".join(f"{r['frequency_hz']:>8.1f}{'' if r['follows'] else '*'}{' ' if r['follows'] else ''}" for r in rows)
        cv = sum(r["interval_cv"] for r in rows) / len(rows)
        # A law without a felt band places no strength.
        placed = [r["strength"] for r in rows if r["strength"] is not None]
        st = f"{sum(placed) / len(placed):.2f}" if placed else "-"
        lines.append(f"  {n:{width}}{cells}   {cv:.2f}, {st}")
    lines.append(f"  told apart at equal speed: {rep.pairs - len(rep.close_pairs)}/{rep.pairs} pairs "
                 f"({rep.distinct_share * 100:.1f} %); followed by the wire: "
                 f"{sum(r['follows'] for r in rep.rows)}/{len(rep.rows)}")
    if rep.close_pairs:
        lines.append("  closer than one JND:")
        for p in rep.close_pairs:
            ratio = "inf" if not math.isfinite(p["frequency_ratio"]) else f"{p['frequency_ratio']:.3f}"
            lines.append(f"    {p['speed_mm_s']:>5g} mm/s  {p['a']} / {p['b']}  (frequency ratio {ratio})")
    return "\n".join(lines)


def _audio_table(rows: list[dict[str, Any]], speeds: tuple[float, ...]) -> str:
    """The voice coil's signal per texture and speed: spectral centroid [Hz] and RMS [dBFS]."""
    names = list(dict.fromkeys(r["texture"] for r in rows))
    width = max(10, *(len(n) for n in names))
    lines = ["voice coil (the tip's acceleration, 20 .. 1000 Hz): spectral centroid [Hz] / RMS [dB full scale]",
             f"  {'texture':{width}}" + "".join(f"{v:>13g}" for v in speeds)]
    for n in names:
        cells = ""
        for r in (r for r in rows if r["texture"] == n):
            db = 20 * math.log10(r["rms_full_scale"]) if r["rms_full_scale"] > 0 else -math.inf
            cells += f"{r['centroid_hz']:>7.0f} /{db:>4.0f}"
        lines.append(f"  {n:{width}}{cells}")
    return "\n".join(lines)


def _serial_table(rows: list[dict[str, Any]], speeds: tuple[float, ...], circuit: str) -> str:
    """What reached the board's pin per texture and speed: pulses [1/s] / p95 timing error [ms],
    and the pulses the board's heat estimate shortened or skipped."""
    names = list(dict.fromkeys(r["texture"] for r in rows))
    width = max(10, *(len(n) for n in names))
    steady = bool(rows) and rows[0]["rendering"] == "steady"
    what = ("pulses [1/s] on the pin (the windowed drive, sent with SET)" if steady else
            "pulses [1/s] on the pin / p95 |pin - rendered event| [ms]")
    lines = [f"serial link to the controller firmware ({circuit}; virtual board, simulated time): {what}",
             f"  {'texture':{width}}" + "".join(f"{v:>14g}" for v in speeds)
             + "   pulses on the pin / rendered, shortened, skipped (all speeds)"]
    for n in names:
        own = [r for r in rows if r["texture"] == n]
        cells = ""
        for r in own:
            p95 = r["event_p95_ms"]
            cells += f"{r['pulses_per_s']:>14.1f}" if steady or p95 is None else f"{r['pulses_per_s']:>7.1f} /{p95:>5.2f}"
        lines.append(f"  {n:{width}}{cells}   {sum(r['pulses'] for r in own)}/{sum(r['rendered'] for r in own)}, "
                     f"{sum(r['shortened'] for r in own)}, {sum(r['skipped'] for r in own)}")
    return "\n".join(lines)
