"""The pen page on a phone and on a desktop, measured in headless Chromium: geometry, prompts, outputs.

At 390 x 844 in Chromium's mobile emulation (a Playwright device descriptor, touch
events) the surface fills the width, the gallery is in the first screen, the drive
readouts stay in view while a finger strokes, and an uncalibrated phone is asked to
calibrate; on every size the surface says what to do, the audio button says its
state, Fig. 5's f_s label is drawn at a readable size and the Upload button stays in
its column.  The phone's vibration motor is checked against the pulses of the drive
the page received: ``navigator.vibrate`` is recorded by an init script.
"""

from __future__ import annotations

import os
import shutil
import time

import numpy as np
import pytest

from test_browser import (  # noqa: F401  (server: a fixture)
    CHROMIUM, CHROMIUM_ARGS, DEFAULT_MM_PER_PX, Pen, opened_page, pick, server, stroke_across_the_right_edge)

pytestmark = pytest.mark.browser

PHONE_VIEWPORT = {"width": 390, "height": 844}
DESKTOP_VIEWPORT = {"width": 1280, "height": 800}
MAX_RATE_HZ = 25  # vibrate.js

RECORD_VIBRATE = """
window.__vibrations = [];
navigator.vibrate = function (pattern) {
  window.__vibrations.push({ t: performance.now(), pattern: Array.isArray(pattern) ? Array.from(pattern) : [pattern] });
  return true;
};
"""


@pytest.fixture(scope="module")
def pw():
    """Playwright and a Chromium: (playwright, browser); the devices' descriptors come from the first."""
    if not (os.path.exists(CHROMIUM) or shutil.which(CHROMIUM)):
        pytest.fail(f"Chromium not found at {CHROMIUM}: the browser tests need it (Debian: apt-get install -y chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield p, b
        b.close()


def phone_args(p, viewport=PHONE_VIEWPORT):
    """An Android phone (Pixel 7's descriptor: mobile, touch, 2.625 device px per CSS px) at ``viewport``."""
    d = dict(p.devices["Pixel 7"])
    d.pop("default_browser_type", None)
    d["viewport"] = dict(viewport)
    d["screen"] = {"width": viewport["width"], "height": max(viewport["height"], 900)}
    return d


def opened(pw, server, *, init_script=None, **context_args):
    """test_browser's pen page in a fresh context of this module's browser (any viewport, device)."""
    return opened_page(pw[1], server, init_script, **context_args)


class Finger:
    """A finger on the touch screen: trusted touch events through the DevTools protocol,
    each with its own timestamp (so the speed is exact however late a busy machine is)."""

    def __init__(self, page):
        self.page = page
        self.cdp = page.context.new_cdp_session(page)

    def _send(self, kind, x, y, at_s):
        points = [] if kind == "touchEnd" else [{"x": x, "y": y, "radiusX": 3, "radiusY": 3, "force": 0.5, "id": 1}]
        self.cdp.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": points, "timestamp": at_s})

    def stroke(self, x0, y0, v_px_s, duration_s, during=None, interval_s=0.008):
        """Touch, move right at v_px_s [CSS px/s] for duration_s, finger left down; ``during()``
        is called late in the stroke with the finger moving until it returns something, which is returned."""
        epoch0, t0 = time.time(), time.perf_counter()
        self._send("touchStart", x0, y0, epoch0)
        seen, x = None, x0
        while (t := time.perf_counter() - t0) < duration_s or (during is not None and seen is None):
            if t > 3 * duration_s:
                raise AssertionError("the page never showed the moving finger's drive")
            x = x0 + v_px_s * t
            self._send("touchMove", x, y0, epoch0 + t)
            if during is not None and seen is None and t > 0.6 * duration_s:
                seen = during()
            time.sleep(interval_s)
        self.x, self.y = x, y0
        return seen

    def lift(self):
        self._send("touchEnd", self.x, self.y, time.time())


def box(page, selector):
    b = page.locator(selector).first.bounding_box()
    assert b is not None, f"{selector} is not laid out"
    return b


def inside(inner, outer, slack=0.5):
    return (inner["x"] >= outer["x"] - slack and inner["y"] >= outer["y"] - slack
            and inner["x"] + inner["width"] <= outer["x"] + outer["width"] + slack
            and inner["y"] + inner["height"] <= outer["y"] + outer["height"] + slack)


READOUT_BOXES = """() => ['drive-speed', 'drive-frequency', 'drive-pulse-width'].map((id) => {
    const r = document.querySelector(`[data-testid="${id}"]`).getBoundingClientRect();
    return { id, top: r.top, bottom: r.bottom, left: r.left, right: r.right, text: document.querySelector(`[data-testid="${id}"]`).textContent };
})"""


def assert_in_view(readouts, viewport):
    for r in readouts:
        assert 0 <= r["top"] and r["bottom"] <= viewport["height"], r
        assert 0 <= r["left"] and r["right"] <= viewport["width"], r


def assert_readable_fs_label(page):
    page.wait_for_function("document.querySelector('#spectrum').dataset.label", timeout=20_000)
    label = page.evaluate("JSON.parse(document.querySelector('#spectrum').dataset.label)")
    canvas = box(page, "#spectrum")
    # Drawn at 14 CSS px whatever the panel's size (it was 20 canvas px shown at ~9 CSS px).
    assert label["font_css_px"] >= 12
    assert label["h"] >= 9  # the glyphs' own box, ascent to descent [CSS px]
    on_page = {"x": canvas["x"] + label["x"], "y": canvas["y"] + label["y"], "width": label["w"], "height": label["h"]}
    assert inside(on_page, canvas), (label, canvas)
    # The panel is large enough for it: the label takes under 80 % of the spectrum's width.
    assert label["w"] < 0.8 * canvas["width"]


def assert_upload_in_its_column(page):
    button = box(page, "#upload-form button[type=submit]")
    file_input = box(page, "#upload-file")
    column = box(page, "#upload-panel")
    assert inside(button, column) and inside(file_input, column), (button, file_input, column)


# ---------------------------------------------------------------------------- a phone


def test_on_a_phone_the_page_is_touch_first(pw, server):
    with opened(pw, server, **phone_args(pw[0])) as page:
        vw, vh = PHONE_VIEWPORT["width"], PHONE_VIEWPORT["height"]
        pick(page, "corduroy")
        # Nothing wider than the screen: no sideways scrolling.
        assert page.evaluate("document.documentElement.scrollWidth") <= vw
        # The surface fills the width (it stayed 256 px wide on a 390 px screen).
        surface = box(page, "#surface")
        assert surface["width"] >= vw - 2 * 8 and surface["x"] >= 0 and surface["x"] + surface["width"] <= vw
        # The gallery is in the first screen (it was at the bottom of a 2,148 px page).
        first = box(page, "[data-testid=texture]")
        assert first["y"] + first["height"] <= vh
        assert first["y"] < surface["y"]
        # Not calibrated, on a touch screen: asked to, above the surface.
        prompt = page.get_by_test_id("calibrate-prompt")
        assert prompt.is_visible() and "0.16 mm" in prompt.text_content()
        assert box(page, "[data-testid=calibrate-prompt]")["y"] + 10 < vh
        # The surface says what to do.
        hint = page.get_by_test_id("surface-hint")
        assert hint.is_visible() and "press and drag" in hint.text_content().lower()
        assert inside(box(page, "[data-testid=surface-hint]"), surface)

        # A finger stroke at 40 mm/s: the readouts move and stay in view, the page does not scroll.
        finger = Finger(page)
        y0 = surface["y"] + 0.5 * surface["height"]
        readouts = finger.stroke(surface["x"] + 10, y0, 40.0 / DEFAULT_MM_PER_PX, 0.5, during=lambda: page.evaluate(
            f"() => {{ const d = window.tactilize.lastDrive;"
            f" return d && d.on && !d.resting && Number(document.querySelector('[data-testid=drive-speed]').textContent) > 0"
            f" ? ({READOUT_BOXES})() : null; }}"))
        finger.lift()
        assert readouts is not None
        assert_in_view(readouts, PHONE_VIEWPORT)
        assert float(readouts[0]["text"]) > 0 and float(readouts[1]["text"]) > 0
        assert page.evaluate("window.scrollY") == 0
        assert page.evaluate("window.tactilize.inputMode") in ("pointerrawupdate", "pointermove")
        # After the first stroke the hint has done its work.
        assert not hint.is_visible()
        assert_readable_fs_label(page)
        assert_upload_in_its_column(page)


def test_a_phone_calibrates_with_the_card_upright(pw, server):
    with opened(pw, server, **phone_args(pw[0])) as page:
        pick(page, "linen")
        page.get_by_test_id("calibrate-now").click()
        dialog = page.get_by_test_id("calibration-dialog")
        assert dialog.is_visible()
        # The card's long side (85.60 mm) does not fit a phone: its short side is matched.
        assert page.get_by_test_id("calibration-card-side").text_content() == "53.98"
        # Starting from a phone's typical 0.16 mm per CSS px, not 1/96 inch.
        assert float(page.get_by_test_id("calibration-mm-per-px").input_value()) == pytest.approx(0.16)
        card = box(page, "[data-testid=calibration-card]")
        assert card["width"] == pytest.approx(53.98 / 0.16, abs=1.0) and card["height"] > card["width"]
        assert card["x"] + card["width"] <= PHONE_VIEWPORT["width"]
        page.get_by_test_id("calibration-card-px").fill("330")
        page.get_by_test_id("calibration-save").click()
        page.wait_for_function(f"Math.abs(window.tactilize.mmPerPx - {53.98 / 330}) < 1e-4", timeout=5_000)
        assert not page.get_by_test_id("calibrate-prompt").is_visible()
        # The picture at its physical size, wider than the screen: cut, the surface still the screen's width.
        page.wait_for_function(f"Math.abs(parseFloat(document.querySelector('#picture').style.width) - {67.7333} / window.tactilize.mmPerPx) < 1")
        assert box(page, "#surface")["width"] >= PHONE_VIEWPORT["width"] - 16
        assert page.evaluate("document.documentElement.scrollWidth") <= PHONE_VIEWPORT["width"]


def test_six_side_by_side_on_a_phone_keeps_every_cell_in_reach(pw, server):
    with opened(pw, server, **phone_args(pw[0])) as page:
        page.get_by_test_id("view-six").check()
        page.wait_for_function("window.tactilize.settings && window.tactilize.settings.composite", timeout=10_000)
        comp = page.evaluate("window.tactilize.settings.composite")
        assert len(comp["ids"]) == 6 and comp["cols"] == 1  # 67.7 mm cells: one across a 390 px screen
        frame = box(page, "#frame")
        assert frame["x"] >= 0 and frame["x"] + frame["width"] <= PHONE_VIEWPORT["width"]
        assert page.evaluate("document.documentElement.scrollWidth") <= PHONE_VIEWPORT["width"]


# ---------------------------------------------------------------------------- a desktop


def test_on_a_desktop_the_same_promises_hold(pw, server):
    with opened(pw, server, viewport=DESKTOP_VIEWPORT) as page:
        pick(page, "corduroy")
        vw, vh = DESKTOP_VIEWPORT["width"], DESKTOP_VIEWPORT["height"]
        first = box(page, "[data-testid=texture]")
        assert first["y"] + first["height"] <= vh
        # A mouse or a pen on a desktop: no calibration prompt, but the surface still says what to do.
        assert not page.get_by_test_id("calibrate-prompt").is_visible()
        assert "press and drag" in page.get_by_test_id("surface-hint").text_content().lower()
        assert page.get_by_test_id("surface-hint").is_visible()
        # The surface fills the stage's width, whole copies cut at its edge.
        stage, surface = box(page, "#stage"), box(page, "#surface")
        assert surface["width"] == pytest.approx(stage["width"], abs=1.0)
        assert page.get_by_test_id("audio-toggle").text_content() == "Audio: off"
        assert not page.get_by_test_id("vibrate-toggle").is_visible()  # no touch screen, no motor offered
        pen = Pen(page)
        page.evaluate("window.__readouts = null")
        shown = pen.stroke(surface["x"] + 10, surface["y"] + 30, 40.0 / DEFAULT_MM_PER_PX, duration_s=0.4)
        readouts = page.evaluate(READOUT_BOXES)
        pen.lift(pen.last_x, surface["y"] + 30)
        assert shown is not None and shown["speed"] > 0
        assert_in_view(readouts, DESKTOP_VIEWPORT)
        assert_readable_fs_label(page)
        assert_upload_in_its_column(page)
        # The column is the gallery's: the button is left of the stage.
        assert box(page, "#upload-form button[type=submit]")["x"] + 1 < stage["x"]


def test_a_stroke_past_the_cut_edge_of_a_filled_surface_stops(pw, server):
    # The surface shows whole copies cut at its edge; past the edge is off the picture,
    # as past the edge of one copy is, though the server's map goes on under the cut.
    with opened(pw, server, viewport={"width": 1100, "height": 800}) as page:
        pick(page, "corduroy")
        v = page.evaluate("window.tactilize.visible")
        assert v["mapW"] - v["w"] > 60  # this window cuts the last copy well inside it
        surface = box(page, "#surface")
        pen = Pen(page)
        y = surface["y"] + 40
        # 30 px inside, then 30 px into the part of the map the cut hides.
        drives, x = stroke_across_the_right_edge(page, pen, surface, y, beyond_px=30)
        assert any(d["on"] and d["inside"] for d in drives)
        pen.lift(x, y)


# ---------------------------------------------------------------------------- audio says its state


def test_the_audio_button_says_its_state(pw, server):
    with opened(pw, server, viewport=DESKTOP_VIEWPORT) as page:
        b = page.get_by_test_id("audio-toggle")
        assert b.text_content() == "Audio: off" and b.get_attribute("aria-pressed") == "false"
        b.click()
        page.wait_for_function("document.querySelector('[data-testid=audio-toggle]').dataset.state === 'on'", timeout=10_000)
        assert b.text_content().startswith("Audio: on") and b.get_attribute("aria-pressed") == "true"
        b.click()
        page.wait_for_function("document.querySelector('[data-testid=audio-toggle]').dataset.state === 'off'")
        assert b.text_content() == "Audio: off"
    # Over plain HTTP from a phone there is no AudioWorklet: the button says why and is off.
    with opened(pw, server, viewport=DESKTOP_VIEWPORT, init_script="delete window.AudioWorkletNode;") as page:
        b = page.get_by_test_id("audio-toggle")
        assert b.text_content() == "Audio: needs HTTPS" and b.is_disabled()


# ---------------------------------------------------------------------------- the phone's motor


def played_pulses(calls):
    """The pulses the motor plays: each call's pattern, cut where the next call replaces it.
    Returns [(start_ms, on_ms)] in page time."""
    out = []
    for i, c in enumerate(calls):
        end = calls[i + 1]["t"] if i + 1 < len(calls) else float("inf")
        t, pat = c["t"], c["pattern"]
        for k in range(0, len(pat), 2):
            if t >= end or pat[k] == 0:  # replaced, or a stop
                break
            out.append((t, pat[k]))
            t += pat[k] + (pat[k + 1] if k + 1 < len(pat) else 0)
    return out


def test_the_phones_motor_plays_the_drives_pulses(pw, server):
    p, _ = pw
    with opened(pw, server, init_script=RECORD_VIBRATE, **phone_args(p, {"width": 412, "height": 839})) as page:
        pick(page, "sandpaper")
        toggle = page.get_by_test_id("vibrate-toggle")
        assert toggle.is_visible() and toggle.text_content() == "Vibrate: off"
        surface = box(page, "#surface")
        finger = Finger(page)
        y0 = surface["y"] + 0.5 * surface["height"]
        # Off until tapped: a stroke makes no vibration.
        finger.stroke(surface["x"] + 10, y0, 20.0 / DEFAULT_MM_PER_PX, 0.3)
        finger.lift()
        page.wait_for_function("window.tactilize.lastDrive && !window.tactilize.lastDrive.down", timeout=5_000)
        assert page.evaluate("window.__vibrations") == []

        page.tap("[data-testid=vibrate-toggle]")
        assert toggle.text_content() == "Vibrate: on" and toggle.get_attribute("aria-pressed") == "true"
        results = {}
        for v_mm_s in (20.0, 80.0):  # sandpaper, perceptual: about 21 Hz, then 66 Hz, above the motor's 25 Hz
            page.evaluate("window.__vibrations = []")
            seq0 = page.evaluate("window.tactilize.seq")
            finger.stroke(surface["x"] + 10, y0, v_mm_s / DEFAULT_MM_PER_PX, 0.9)
            # The finger stays down, still: the server says the pen rests; the motor must stop.
            page.wait_for_function(
                f"window.tactilize.drives.some(d => d.seq > {seq0} && d.down && (d.resting || !d.on))", timeout=10_000)
            page.wait_for_function("window.tactilize.vibration.timer === 0", timeout=5_000)
            calls = page.evaluate("window.__vibrations")
            drives = page.evaluate(f"window.tactilize.drives.filter(d => d.seq > {seq0})")
            finger.lift()
            results[v_mm_s] = (calls, drives)

        for v_mm_s, (calls, drives) in results.items():
            moving = [d for d in drives if d["on"] and not d["resting"]]
            still = lambda d: d["down"] and (d["resting"] or not d["on"])  # noqa: E731
            # The pen rests from a still drive to the next moving one (a busy machine may
            # pause the stroke too; the last rest is the finger held still).
            rests, start = [], None
            for d in drives:
                if start is None and still(d) and d["page_ms"] > moving[0]["page_ms"]:
                    start = d["page_ms"]
                elif start is not None and d["on"] and not d["resting"]:
                    rests.append((start, d["page_ms"]))
                    start = None
            assert start is not None, "the finger held still must end in a rest"
            rests.append((start, float("inf")))
            rest_ms = start
            patterns = [c for c in calls if c["pattern"] not in ([0], [])]
            assert len(patterns) >= 3, calls
            # What the API can do: whole milliseconds, at least 1, on/off.
            for c in patterns:
                assert all(isinstance(x, int) and x >= 1 for x in c["pattern"]), c
            # Nothing while the pen rests: no pattern starts then, and one still playing is stopped.
            for a, b in rests:
                assert not [c for c in patterns if a < c["t"] < b], (a, b, calls)
                before = [c for c in calls if c["t"] <= a]
                if before and before[-1]["pattern"] not in ([0], []) and before[-1]["t"] + sum(before[-1]["pattern"]) > a:
                    assert any(c["pattern"] in ([0], []) and a <= c["t"] < b for c in calls), (a, b, calls)
            # The pulses played follow the drive the page received: its rate, at most MAX_RATE_HZ.
            pulses = [pp for pp in played_pulses(calls) if pp[0] < rest_ms]
            starts = np.array([pp[0] for pp in pulses])
            gaps = np.diff(starts)
            assert gaps.min() >= 1000.0 / MAX_RATE_HZ - 1.0, (calls, [(d["page_ms"], d["channels"][0]["pulse_frequency_hz"]) for d in moving])
            f_drive = np.median([d["channels"][0]["pulse_frequency_hz"] for d in moving[len(moving) // 4:]])
            want_ms = 1000.0 / min(f_drive, MAX_RATE_HZ)
            assert np.median(gaps) == pytest.approx(want_ms, rel=0.25) if f_drive < MAX_RATE_HZ else np.median(gaps) >= want_ms - 1
            assert len(pulses) <= (starts[-1] - starts[0]) / 1000.0 * max(d["channels"][0]["pulse_frequency_hz"] for d in moving) + 2
            # A pulse is on for less than the time to the next one.
            assert all(on < gap for (_, on), gap in zip(pulses, gaps))
            results[v_mm_s] = f_drive
        assert results[80.0] > MAX_RATE_HZ > results[20.0]  # the two strokes tested both regimes


SIMULATE_PLAYER = """async ({ late_ms, work_ms, seed }) => {
  // vibrate.js on an injected clock: timers fire up to late_ms late, and up to work_ms
  // pass between reading the clock and the call (a busy page); a seeded generator.
  const m = await import('/static/vibrate.js');
  let t = 0, s = seed;
  const rand = () => ((s = (s * 1103515245 + 12345) % 2147483648) / 2147483648);
  const calls = [], timers = [];
  let ids = 0;
  const nav = { vibrate: (p) => { calls.push({ t, pattern: Array.isArray(p) ? Array.from(p) : [p] }); return true; } };
  const now = () => { t += rand() * work_ms; return t; };
  const v = new m.VibrationPulses({ nav, now,
    setTimer: (f, ms) => { const id = ++ids; timers.push({ id, at: t + ms + rand() * late_ms, f }); return id; },
    clearTimer: (id) => { const i = timers.findIndex((x) => x.id === id); if (i >= 0) timers.splice(i, 1); } });
  const runTo = (end) => {
    for (;;) {
      timers.sort((a, b) => a.at - b.at);
      if (!timers.length || timers[0].at > end) { t = Math.max(t, end); return; }
      const x = timers.shift(); t = Math.max(t, x.at); x.f();
    }
  };
  v.start();
  // A stroke: the drive's frequency changes every 50 ms (12 .. 70 Hz), then the pen rests.
  for (let k = 0; k < 40; k++) {
    v.setDrives([{ pulse_frequency_hz: 12 + 58 * rand(), strength: rand(), amplitude: 1 }]);
    runTo(t + 50);
  }
  const restAt = t;
  v.setDrives([{}, {}]);
  runTo(t + 1000);
  return { calls, restAt, maxRate: m.MAX_RATE_HZ };
}"""


@pytest.mark.parametrize("late_ms, work_ms, seed", [(0.0, 0.0, 1), (6.0, 0.3, 2), (30.0, 2.0, 3), (12.0, 4.0, 4)])
def test_the_motor_player_never_doubles_or_crowds_a_pulse(pw, server, late_ms, work_ms, seed):
    # On an injected clock with late timers and slow work: every pulse the motor
    # plays is at least 1/MAX_RATE_HZ after the one before, whole ms >= 1, none after the rest.
    with opened(pw, server, viewport=DESKTOP_VIEWPORT) as page:
        out = page.evaluate(SIMULATE_PLAYER, {"late_ms": late_ms, "work_ms": work_ms, "seed": seed})
    calls, rest = out["calls"], out["restAt"]
    patterns = [c for c in calls if c["pattern"] not in ([0], [])]
    assert len(patterns) > 10
    assert all(isinstance(x, int) and x >= 1 for c in patterns for x in c["pattern"])
    pulses = played_pulses(calls)
    starts = np.array([p[0] for p in pulses])
    assert np.diff(starts).min() >= 1000.0 / out["maxRate"] - 1e-6
    assert all(c["t"] <= rest for c in patterns)
    # The pen rested: whatever was playing was stopped then.
    assert calls[-1]["pattern"] in ([0], []) and calls[-1]["t"] >= rest
