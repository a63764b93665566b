"""Figures for the command line (``simulate --plot``, ``envelope --plot``, ``analyze --plot``).

matplotlib is an optional extra (``tactilize[plot]``); without it these raise a
:class:`~tactilize.errors.MissingExtraError` naming the option that asked for a plot.
Only the CLI draws these, so they live beside it; the experiments draw their
own figures (``tactilize.experiments.figures``).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import TactilizeError, check_output_path

if TYPE_CHECKING:  # types only: the plots load their libraries when drawn
    from ..features import TextureFeatures
    from ..image import TextureImage
    from ..maps.texturemap import TextureMap

__all__ = ["plot_paths", "plot_simulation", "plot_envelope", "plot_profile_report", "plot_spectrum"]


def _pyplot(option: str):
    """matplotlib.pyplot on a file backend, or a one-line error naming the option."""
    from ..extras import require

    matplotlib = require("matplotlib", option, "plot")
    matplotlib.use("Agg")
    return require("matplotlib.pyplot", option, "plot")


def plot_option(path: str, option: str = "--plot") -> None:
    """Refuse ``--plot PATH`` in one line before any work: matplotlib missing, or a
    path that cannot be written (:func:`tactilize.errors.check_output_path`)."""
    check_output_path(path)
    _pyplot(option)


def plot_paths(path: str, images: Sequence[str]) -> list[str]:
    """Where ``--plot PATH`` draws each of ``images``: PATH itself for one image;
    for several, PATH's stem, a dash and the image's stem (``fig.png``, ``a/cloth.jpg``
    -> ``fig-cloth.png``), with a number where two images share a stem."""
    if len(images) == 1:
        return [path]
    base = Path(path)
    stems = [Path(im).stem for im in images]
    out = []
    for i, stem in enumerate(stems):
        name = f"{base.stem}-{stem}" + (f"-{i + 1}" if stems.count(stem) > 1 else "")
        out.append(str(base.with_name(name + base.suffix)))
    return out


def _save(plt: Any, fig: Any, path: str) -> None:
    try:
        fig.savefig(path, dpi=120, bbox_inches="tight")
    except (OSError, ValueError) as exc:
        raise TactilizeError(path, f"cannot write the plot ({exc})") from None
    finally:
        plt.close(fig)


def plot_simulation(
    result: Any,
    spec: Any,
    summary: dict[str, Any],
    frequency_hz: float,
    pulse_width_ms: float,
    current_ma: float,
    path: str,
    option: str = "--plot",
) -> None:
    """Temperature [°C], martensite fraction and displacement [µm] over time [s].

    ``result`` is a :class:`~tactilize.actuators.sma.SimulationResult`, ``spec``
    its wire, ``summary`` the simulate report (``follows``, ``displacement_pp_um``).
    """
    plt = _pyplot(option)
    step = max(1, result.time_s.size // 20000)  # a readable line, not 10^6 points
    t = result.time_s[::step]
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 7))
    axes[0].plot(t, result.temperature_c[::step], lw=0.8)
    for y in (spec.austenite_start_c, spec.austenite_finish_c):
        axes[0].axhline(y, color="grey", lw=0.5, ls="--")
    axes[0].set_ylabel("temperature [°C]")
    axes[1].plot(t, result.martensite_fraction[::step], lw=0.8)
    axes[1].set_ylabel("martensite fraction")
    axes[2].plot(t, result.displacement_m[::step] * 1e6, lw=0.8)
    axes[2].set_ylabel("displacement [µm]")
    axes[2].set_xlabel("time [s]")
    axes[0].set_title(
        f"{spec.name} wire, {frequency_hz:g} Hz, {pulse_width_ms:g} ms, {current_ma:g} mA: "
        f"{'follows' if summary['follows'] else 'does not follow'}, {summary['displacement_pp_um']:.2f} µm p-p"
    )
    _save(plt, fig, path)


def plot_envelope(rows: list[dict[str, Any]], spec: Any, circuit: Any, path: str, option: str = "--plot") -> None:
    """The felt band (shaded) and the envelope's largest pulse width [ms] per frequency [Hz].

    ``rows`` are the ``bands`` of ``tactilize envelope --json``.
    """
    plt = _pyplot(option)
    fig, ax = plt.subplots(figsize=(7, 5))
    f = [r["frequency_hz"] for r in rows]
    lo = [r["felt_band_width_s"][0] * 1e3 for r in rows]
    hi = [r["felt_band_width_s"][1] * 1e3 for r in rows]
    ax.fill_between(f, lo, hi, alpha=0.25, label="felt band (full switch, relaxed wire)")
    ax.loglog(f, [r["max_width_s"] * 1e3 for r in rows], marker="o", ms=3, label="envelope: largest width")
    ax.set_xlabel("pulse frequency [Hz]")
    ax.set_ylabel("pulse width [ms]")
    ax.set_title(f"{spec.name} wire on {circuit.name}: felt band and envelope")
    ax.legend(fontsize=8)
    _save(plt, fig, path)


def plot_profile_report(report: Any, path: str, *, jnd: float = 0.2, option: str = "--plot") -> None:
    """Pulse frequency [Hz] against stroking speed [mm/s] per texture, each line with a band
    one frequency JND wide, over the band where the wire is felt (shaded)."""
    plt = _pyplot(option)
    fig, ax = plt.subplots(figsize=(7.5, 5))
    ax.axhspan(1.0, 300.0, color="0.92", label="the wire follows (1 .. 300 Hz)")
    names = list(dict.fromkeys(r["texture"] for r in report.rows))
    half = (1.0 + jnd) ** 0.5
    for n in names:
        rows = [r for r in report.rows if r["texture"] == n]
        v = [r["speed_mm_s"] for r in rows]
        f = [r["frequency_hz"] for r in rows]
        line = ax.plot(v, f, marker="o", ms=3, label=n)[0]
        ax.fill_between(v, [x / half for x in f], [x * half for x in f], color=line.get_color(), alpha=0.15, lw=0)
        missed = [(a, b) for a, b, r in zip(v, f, rows) if not r["follows"]]
        if missed:
            ax.scatter(*zip(*missed), marker="x", color="k", zorder=3)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("stroking speed [mm/s]")
    ax.set_ylabel("pulse frequency [Hz]")
    ax.set_title(f"profile {report.profile}: {report.distinct_share * 100:.0f} % of texture pairs one JND apart")
    ax.legend(fontsize=7, ncol=2)
    _save(plt, fig, path)


def plot_spectrum(
    img: TextureImage, features: TextureFeatures, texture_map: TextureMap | None, path: str, option: str = "--plot"
) -> dict[str, Any]:
    """The paper's Fig. 5 for one picture: the image, its 2-D spectrum (log
    magnitude, DC centred) with the dominant peak marked with f_s [cycles/mm]
    and i_s, and the texture map's f_s per tile [cycles/mm].

    The same data as the pen page's figure (:func:`tactilize.maps.spectrumview.spectrum_view`);
    returns it without the pixels.
    """
    from ..maps.spectrumview import spectrum_view

    plt = _pyplot(option)
    view = spectrum_view(img.pixels, features, texture_map)
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
    w_mm, h_mm = img.width_m * 1e3, img.height_m * 1e3
    axes[0].imshow(img.pixels, cmap="gray", vmin=0, vmax=1, extent=(0, w_mm, h_mm, 0))
    axes[0].set_title(f"{img.source}: {w_mm:.1f} x {h_mm:.1f} mm")
    axes[0].set_xlabel("x [mm]")
    axes[0].set_ylabel("y [mm]")
    ch, cw = view["crop"]
    bx, by = view["bin_per_mm"]
    # Axes in cycles/mm, DC at 0, ky up (the spectrum's top row is the highest ky).
    ext = (-(cw // 2) * bx, (cw - cw // 2) * bx, -(ch - ch // 2) * by, (ch // 2) * by)
    axes[1].imshow(view["spectrum_u8"], cmap="magma", extent=ext)
    axes[1].set_xlabel("k_x [cycles/mm]")
    axes[1].set_ylabel("k_y [cycles/mm]")
    fs, i_s = view["spatial_frequency_per_mm"], view["spectral_intensity"]
    if view["peak"]:
        kx, ky = features.wave_vector_per_m
        for sgn in (1, -1):
            axes[1].plot(sgn * kx * 1e-3, sgn * ky * 1e-3, "o", mfc="none", mec="cyan", ms=12, mew=1.5)
        axes[1].annotate(f"f_s = {fs:.3f} cycles/mm\ni_s = {i_s:.3f}", (kx * 1e-3, ky * 1e-3), xytext=(8, 8),
                         textcoords="offset points", color="cyan", fontsize=9)
    axes[1].set_title("2-D spectrum, log |F|, DC centred")
    tiles = view["tiles"]
    im = axes[2].imshow(tiles["spatial_frequency_per_mm"], cmap="viridis", extent=(0, w_mm, h_mm, 0))
    fig.colorbar(im, ax=axes[2], label="f_s per tile [cycles/mm]")
    axes[2].set_title(f"texture map: {tiles['rows']} x {tiles['cols']} tiles of {tiles['tile_mm'][0]:.1f} mm")
    axes[2].set_xlabel("x [mm]")
    fig.tight_layout()
    _save(plt, fig, path)
    view.pop("spectrum_u8")
    return view
