"""Figures of the wire model for the command line (``simulate --plot``, ``envelope --plot``).

matplotlib is an optional extra (``tactilize[plot]``); without it these raise a
:class:`~tactilize.errors.TactilizeError` naming the option that asked for a plot.
Only the CLI draws these, so they live beside it; the experiments draw their
own figures (``tactilize.experiments.figures``).
"""

from __future__ import annotations

from typing import Any

from ..errors import TactilizeError

__all__ = ["plot_simulation", "plot_envelope"]


def _pyplot(option: str):
    """matplotlib.pyplot on a file backend, or a one-line error naming the option."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise TactilizeError(option, "needs matplotlib (pip install 'tactilize[plot]')") from None
    return plt


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
