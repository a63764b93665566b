"""The page's audio in a real headless Chromium: the surface rendering's pulse events play in the
AudioWorklet as acceleration wavelets (docs/surfaces.md, "Voice coils and the page's audio").
Fixtures and the pen come from test_browser (the server: ``tactilize serve`` on a free port)."""

from __future__ import annotations

import numpy as np
import pytest

from test_browser import (  # noqa: F401  (server, browser, page: fixtures)
    DEFAULT_MM_PER_PX, Pen, browser, page, pick, server, surface_box)

pytestmark = pytest.mark.browser


def test_surface_audio_plays_a_wavelet_per_pulse(page):
    """The surface rendering's page audio: each pulse event the server schedules plays once,
    as a wavelet in the AudioWorklet (counted there), and no steady train plays meanwhile."""
    pick(page, "sandpaper")
    page.get_by_test_id("profile").select_option("surface")
    page.wait_for_function("window.tactilize.settings.profile === 'surface'")
    page.get_by_test_id("audio-toggle").click()
    page.wait_for_function("window.tactilize.audio.on && window.tactilize.audio.ctx.state === 'running'", timeout=10_000)
    pen = Pen(page)
    box = surface_box(page)
    y = box["y"] + box["height"] / 2
    page.evaluate("window.tactilize.pulses = 0")
    pen.stroke(box["x"] + 20, y, 40 / DEFAULT_MM_PER_PX, duration_s=0.8)
    pen.lift(pen.last_x, y)
    page.wait_for_function("window.tactilize.lastDrive && !window.tactilize.lastDrive.on", timeout=10_000)
    pulses = page.evaluate("window.tactilize.pulses")
    assert pulses >= 10, pulses
    # The bumps crossed before the lift play even when the audio runs late (a loaded machine).
    page.wait_for_function(f"window.tactilize.audio.played >= {0.8 * pulses}", timeout=10_000)
    page.wait_for_timeout(200)  # and nothing more comes: the pen is up
    played = page.evaluate("window.tactilize.audio.played")
    # One wavelet per pulse: none twice however often a batch re-sends it (a few at the
    # stroke's end may have been scheduled and not yet due when the pen lifted).
    assert 0.8 * pulses <= played <= pulses + 2, (played, pulses)
    # ...none twice: the server never sends two pulses closer than 1/300 s, and a re-sent
    # one would land within a millisecond or two of itself.
    at = sorted(page.evaluate("window.tactilize.audio.playedAt"))
    assert len(at) == played and min(np.diff(at)) > 0.003, np.diff(at)
    drives = page.evaluate("window.tactilize.drives.filter(d => d.on && d.rendering === 'surface')")
    assert any(d["wavelets"] for d in drives)
    assert all(len(row) == 3 and row[2] > 0 for d in drives for row in d["wavelets"])
