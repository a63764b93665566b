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


def plot_envelope(env: Any, spec: Any, path: str, option: str = "--plot") -> None:
    """The vibrating band (shaded) and the largest allowed pulse width [ms] per frequency [Hz] and current."""
    plt = _pyplot(option)
    fig, ax = plt.subplots(figsize=(7, 5))
    for j, cur in enumerate(env.currents_a):
        hi = [row[j] * 1e3 for row in env.max_width_s]
        lo = [row[j] * 1e3 for row in env.min_follow_width_s]
        line = ax.loglog(env.frequencies_hz, hi, marker="o", ms=3, label=f"{cur * 1e3:.0f} mA: largest allowed")[0]
        ax.fill_between(env.frequencies_hz, lo, hi, color=line.get_color(), alpha=0.15)
    ax.set_xlabel("pulse frequency [Hz]")
    ax.set_ylabel("pulse width [ms]")
    ax.set_title(f"{spec.name} wire: vibrating band (shaded) and the envelope")
    ax.legend(fontsize=8)
    _save(plt, fig, path)
