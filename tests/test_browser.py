"""End to end in a real headless Chromium: the page, a pen stroke at two speeds, lift, calibration.

The server is ``tactilize serve`` itself, started as a subprocess on a free
loopback port.  Pen input is real: Chrome DevTools Protocol
``Input.dispatchMouseEvent`` with ``pointerType: "pen"`` makes the browser
produce trusted pen Pointer Events (pressure, coalescing, timestamps), exactly
the path a tablet takes.

These tests need Debian's ``chromium`` (``apt-get install chromium``) and the
``playwright`` Python package; without them they FAIL with a message saying so
(they are never skipped: CI must run them).
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

pytestmark = pytest.mark.browser

CHROMIUM = os.environ.get("TACTILIZE_CHROMIUM", "/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--autoplay-policy=no-user-gesture-required",
]
DEFAULT_MM_PER_PX = 25.4 / 96


@contextlib.contextmanager
def serving(tmp_path_factory, *args: str):
    """``tactilize serve --no-open --port 0 ARGS`` in a process of its own: its address.

    The server's log goes to a file and its stdout is drained: a pipe nobody reads
    fills (64 KiB, about fifty tests' worth of log lines) and then blocks the
    server for good -- every later test saw "never showed a drive"."""
    log = open(tmp_path_factory.mktemp("serve") / "serve.log", "w+")
    proc = subprocess.Popen([sys.executable, "-m", "tactilize.cli", "serve", "--no-open", "--port", "0", *args],
                            stdout=subprocess.PIPE, stderr=log, text=True)
    line = proc.stdout.readline()
    m = re.search(r"http://127\.0\.0\.1:\d+/", line)
    if not m:
        proc.kill()
        log.seek(0)
        pytest.fail(f"tactilize serve did not print its address: {line!r} {log.read()[-2000:]}")
    threading.Thread(target=proc.stdout.read, daemon=True).start()
    try:
        yield m.group(0)
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
        log.close()


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    # The page's steady numbers are pinned on the perceptual preset (the default is the
    # surface rendering; tests/test_surface_profile.py drives its session).
    with serving(tmp_path_factory, "--profile", "perceptual") as url:
        yield url


@pytest.fixture(scope="module")
def browser():
    if not (os.path.exists(CHROMIUM) or shutil.which(CHROMIUM)):
        pytest.fail(
            f"Chromium not found at {CHROMIUM}: the browser tests need it "
            "(Debian: apt-get install -y chromium; or set TACTILIZE_CHROMIUM)"
        )
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.fail("the browser tests need the playwright Python package (pip install playwright)")
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()


@contextlib.contextmanager
def opened_page(browser, server, init_script=None, **context_args):
    """The pen page, loaded and connected, in a fresh browser context; on leaving,
    the page must have thrown no error.  ``init_script`` runs before the page's own."""
    context_args.setdefault("viewport", {"width": 1400, "height": 900})
    ctx = browser.new_context(**context_args)
    if init_script:
        ctx.add_init_script(init_script)
    pg = ctx.new_page()
    errors: list[str] = []
    pg.on("pageerror", lambda e: errors.append(str(e)))
    try:
        pg.goto(server)
        pg.wait_for_selector("body[data-ready=true]", timeout=30_000)
        pg.wait_for_function("window.tactilize.settings !== null", timeout=30_000)
        yield pg
    finally:
        ctx.close()
    assert not errors, errors


@pytest.fixture()
def page(browser, server):
    with opened_page(browser, server) as pg:
        yield pg


def pick(page, texture_id):
    page.locator(f'[data-testid=texture][data-id="{texture_id}"]').click()
    page.wait_for_function(f"window.tactilize.settings && window.tactilize.settings.texture === '{texture_id}'")
    page.wait_for_function("document.querySelector('#picture').complete")


class Pen:
    """A pen driven through the DevTools protocol: trusted pen pointer events."""

    def __init__(self, page):
        self.page = page
        self.cdp = page.context.new_cdp_session(page)

    def _send(self, kind, x, y, buttons, force=0.6, at_s=None):
        # ``at_s`` (seconds since the epoch) becomes the event's own timestamp.
        # The strokes below compute the position and the timestamp from one clock
        # reading, so the speed the page measures is the speed asked for however
        # late a loaded machine delivers the event.
        self.cdp.send(
            "Input.dispatchMouseEvent",
            {
                "type": kind,
                "timestamp": time.time() if at_s is None else at_s,
                "x": x,
                "y": y,
                "button": "left",
                "buttons": buttons,
                "clickCount": 1 if kind != "mouseMoved" else 0,
                "pointerType": "pen",
                "force": force,
                "tiltX": 10,
                "tiltY": -5,
            },
        )

    READ = """() => {
        const d = window.tactilize.lastDrive;
        if (!d || !d.on || d.resting || !(d.speed_mm_s > 0)) return null;
        const v = (id) => Number(document.querySelector(`[data-testid="${id}"]`).textContent);
        return {frequency: v('drive-frequency'), width: v('drive-pulse-width'), duty: v('drive-duty'),
                amplitude: v('drive-amplitude'), speed: v('drive-speed'), seq: d.seq};
    }"""

    def stroke(self, x0, y0, v_px_s, duration_s=0.5, interval_s=0.004):
        """Press, move right at v_px_s [CSS px/s] in real time; returns the drive
        the data-testid elements showed late in the stroke, with the pen moving."""
        epoch0 = time.time()
        t0 = time.perf_counter()
        self._send("mousePressed", x0, y0, 1, at_s=epoch0)
        x = x0
        shown = None
        while (t := time.perf_counter() - t0) < duration_s or shown is None:
            if t > 3 * duration_s:
                raise AssertionError("the page never showed a drive for the moving pen")
            # Position and timestamp from the same clock reading: the speed is
            # exact whatever the pacing.
            x = x0 + v_px_s * t
            self._send("mouseMoved", x, y0, 1, at_s=epoch0 + t)
            if t > 0.6 * duration_s and shown is None:
                # Read while the pen still moves (a pen at rest has speed 0).
                shown = self.page.evaluate(self.READ)
            time.sleep(interval_s)
        self.last_x = x
        return shown

    def lift(self, x, y):
        self._send("mouseReleased", x, y, 0, force=0.0)

    def keep_moving_until(self, y, v_px_s, check, span_px=60.0, timeout_s=30.0):
        """With the pen down at ``self.last_x``, go on stroking at ``v_px_s`` [CSS px/s],
        back and forth over ``span_px``, and call ``check()`` every 40 ms of strokes
        until it returns something truthy, which is returned.

        A check that looks at the page (a screenshot) may take hundreds of ms on a
        loaded machine; the pen then moves on the clock (position and timestamp
        from one reading), so the drive the page shows is that of a moving pen
        whenever the check runs, however late.  Fails after ``timeout_s``."""
        epoch0, x_start = time.time(), self.last_x
        deadline = time.monotonic() + timeout_s
        while True:
            for _ in range(10):
                t = time.time() - epoch0
                s = (v_px_s * t) % (2 * span_px)
                x = x_start + (s if s < span_px else 2 * span_px - s)
                self._send("mouseMoved", x, y, 1, at_s=epoch0 + t)
                time.sleep(0.004)
            self.last_x = x
            got = check()
            if got:
                return got
            if time.monotonic() > deadline:
                raise AssertionError(f"the page never showed what was awaited within {timeout_s} s of stroking")


def surface_box(page):
    return page.locator("#picture").bounding_box()


def steady_drives(page, seq_from):
    """Drives received for one stroke, without its first 100 ms (speed estimate settling)."""
    # speed > 0: leave out the "pen resting" drive the server sends after a silence.
    drives = page.evaluate(f"window.tactilize.drives.filter(d => d.seq > {seq_from} && d.on && !d.resting)")
    t0 = drives[0]["t_s"]
    return [d for d in drives if d["t_s"] - t0 > 0.1]


def expected_frequency(texture_id, speed_mm_s, profile="perceptual"):  # the fixture server's profile
    from tactilize.mapping import Profile
    from tactilize.data import builtin_map

    feat = builtin_map(texture_id).whole
    return Profile.preset(profile).drive(feat, speed_mm_s / 1e3).pulse_frequency_hz


def test_page_gallery_and_surface(page):
    items = page.locator("[data-testid=texture]")
    assert items.count() >= 6
    surface = page.get_by_test_id("surface")
    assert surface.evaluate("e => getComputedStyle(e).touchAction") == "none"
    pick(page, "linen")
    box = surface_box(page)
    # shown at its physical size: 67.7 mm at 1/96 inch per CSS px = 256 px
    assert box["width"] == pytest.approx(67.7333 / DEFAULT_MM_PER_PX, abs=1.0)
    assert page.get_by_test_id("texture-name").text_content() == "Linen"
    for tid in ("drive-frequency", "drive-pulse-width", "drive-duty", "drive-amplitude", "drive-speed"):
        el = page.get_by_test_id(tid)
        assert float(el.text_content()) == 0.0
        assert el.get_attribute("title")  # says the unit


def test_fig5_is_above_the_fold_on_a_laptop_screen(browser, server):
    """At 1280 x 800 the paper's Fig. 5 (picture, spectrum, tile map) is on the first
    screen, beside the picture and the wire's plot, without scrolling."""
    with opened_page(browser, server, viewport={"width": 1280, "height": 800}) as pg:
        pick(pg, "corduroy")
        pg.wait_for_function("document.querySelector('#spectrum-name').textContent !== '–'")
        fig = pg.get_by_test_id("spectrum-figure").bounding_box()
        plot = pg.get_by_test_id("plot").bounding_box()
        assert fig is not None and plot is not None
        assert fig["y"] + fig["height"] <= 800, fig
        assert plot["height"] >= 100  # the plot stays readable
        assert pg.evaluate("document.scrollingElement.scrollTop") == 0


def test_pen_stroke_two_speeds_then_lift(page):
    pick(page, "corduroy")
    pen = Pen(page)
    box = surface_box(page)
    x0, y0 = box["x"] + 15, box["y"] + 40
    results = {}
    for v_mm_s in (10.0, 40.0):
        seq_before = page.evaluate("window.tactilize.seq")
        shown = pen.stroke(x0, y0, v_mm_s / DEFAULT_MM_PER_PX)
        pen.lift(pen.last_x, y0)
        # Lift: everything stops, at once, on the server's word.
        page.wait_for_function(
            """() => document.querySelector('[data-testid=drive-frequency]').textContent === '0.0'
                 && document.querySelector('[data-testid=surface]').dataset.state === 'off'
                 && window.tactilize.lastDrive && !window.tactilize.lastDrive.down""",
            timeout=5_000,
        )
        assert float(page.get_by_test_id("drive-duty").text_content()) == 0.0
        steady = steady_drives(page, seq_before)
        # Drives come a batch of samples per frame; a loaded machine draws fewer
        # frames (9 in 0.4 s seen under three busy loops), so ask for enough for
        # the medians below, not for a frame rate.
        assert len(steady) >= 5, "the page should report the drives of a moving pen"
        results[v_mm_s] = (shown, steady)
    (slow, slow_steady), (fast, fast_steady) = results[10.0], results[40.0]
    # What the data-testid elements showed while the pen was down.
    assert fast["frequency"] > 1.5 * slow["frequency"]
    assert fast["speed"] > 2.5 * slow["speed"]
    # The wire's controller sizes the pulse (slow strokes: few, strong pulses): within
    # half a period and at most 10 % duty.
    assert 0 < slow["width"] <= 500.0 / slow["frequency"] and 0 < slow["duty"] <= 10.0
    assert 0.0 <= slow["amplitude"] <= 1.0
    # As the profile says, within the jitter of a real-time stroke.
    for v, steady in ((10.0, slow_steady), (40.0, fast_steady)):
        speed = np.median([d["speed_mm_s"] for d in steady])
        freq = np.median([d["channels"][0]["pulse_frequency_hz"] for d in steady])
        assert speed == pytest.approx(v, rel=0.15)
        assert freq == pytest.approx(expected_frequency("corduroy", v), rel=0.15)
        # Real pen events: pressure came through, and both channels are driven.
        assert steady[-1]["pressure"] == pytest.approx(0.6, abs=0.01)
        chans = steady[-1]["channels"]
        assert len(chans) == 2 and chans[0]["pulse_frequency_hz"] == chans[1]["pulse_frequency_hz"]
        # On the (simulated) SMA wire both pins play the texture at the paper's full
        # current: a phantom split would lower the current out of the vibrating band.
        assert steady[-1]["direction_deg"] == pytest.approx(0.0, abs=10.0)
        assert chans[0]["amplitude"] == chans[1]["amplitude"] == pytest.approx(1.0)


def stroke_across_the_right_edge(page, pen, box, y, beyond_px):
    """Press 30 px inside the surface's right edge and drag to ``beyond_px`` past it, 2 px every 4 ms
    (about 130 mm/s); wait until the page shows the pen down, outside and off.  Returns the drives
    received since the press and the pen's last x."""
    x = box["x"] + box["width"] - 30
    seq0 = page.evaluate("window.tactilize.seq")
    pen._send("mousePressed", x, y, 1)
    while x < box["x"] + box["width"] + beyond_px:
        x += 2
        pen._send("mouseMoved", x, y, 1)
        time.sleep(0.004)  # the pen's pace, not a wait for the page
    page.wait_for_function(
        "() => { const d = window.tactilize.lastDrive; return d && d.seq >= window.tactilize.seq && d.down && !d.inside && !d.on; }",
        timeout=5_000,
    )
    return page.evaluate(f"window.tactilize.drives.filter(d => d.seq > {seq0})"), x


def test_leaving_the_picture_stops(page):
    # One copy of the picture (not repeated to fill the screen): its right edge is the surface's.
    page.get_by_test_id("fill").uncheck()
    pick(page, "corduroy")
    page.wait_for_function("window.tactilize.settings && !window.tactilize.settings.repeat")
    pen = Pen(page)
    box = surface_box(page)
    y = box["y"] + 40
    drives, x = stroke_across_the_right_edge(page, pen, box, y, beyond_px=60)
    assert any(d["on"] and d["inside"] for d in drives)  # it was driven while over the picture
    assert page.get_by_test_id("drive-frequency").text_content() == "0.0"
    assert page.get_by_test_id("surface").get_attribute("data-state") == "off"
    pen.lift(x, y)


def test_calibration_changes_reported_speed(page):
    pick(page, "corduroy")
    pen = Pen(page)
    v_px_s = 10.0 / DEFAULT_MM_PER_PX  # 10 mm/s before calibration
    box = surface_box(page)
    before = pen.stroke(box["x"] + 10, box["y"] + 30, v_px_s, duration_s=0.4)
    pen.lift(pen.last_x, box["y"] + 30)

    # The user matches the card: 162 CSS px for 85.60 mm (0.528 mm per px, about twice 1/96 inch).
    page.get_by_test_id("calibrate").click()
    page.get_by_test_id("calibration-card-px").fill("162")
    mm_per_px = float(page.get_by_test_id("calibration-mm-per-px").input_value())
    assert mm_per_px == pytest.approx(85.60 / 162, rel=1e-4)
    page.get_by_test_id("calibration-save").click()
    page.wait_for_function(
        f"window.tactilize.settings && Math.abs(window.tactilize.settings.mm_per_px - {mm_per_px}) < 1e-4", timeout=5_000
    )
    # The picture keeps its physical size: fewer CSS px now.
    box2 = surface_box(page)
    assert box2["width"] == pytest.approx(67.7333 / mm_per_px, abs=1.0)

    seq0 = page.evaluate("window.tactilize.seq")
    after = pen.stroke(box2["x"] + 10, box2["y"] + 30, v_px_s, duration_s=0.4)
    pen.lift(pen.last_x, box2["y"] + 30)
    ratio = mm_per_px / DEFAULT_MM_PER_PX
    assert after["speed"] > 1.5 * before["speed"]
    speed = np.median([d["speed_mm_s"] for d in steady_drives(page, seq0)])
    assert speed == pytest.approx(10.0 * ratio, rel=0.15)

    # Kept per browser: a reload still uses it.
    page.reload()
    page.wait_for_function("window.tactilize && window.tactilize.settings !== null", timeout=30_000)
    assert page.evaluate("window.tactilize.mmPerPx") == pytest.approx(mm_per_px, rel=1e-6)
    assert "calibrated" in page.get_by_test_id("calibration-note").text_content()
    page.get_by_test_id("calibrate").click()
    page.get_by_test_id("calibration-reset").click()
    # The dialog's close event, which applies the reset, is queued after the click returns.
    page.wait_for_function(f"Math.abs(window.tactilize.mmPerPx - {DEFAULT_MM_PER_PX}) < 1e-9", timeout=5_000)
    assert page.evaluate("window.tactilize.mmPerPx") == pytest.approx(DEFAULT_MM_PER_PX)


def test_coalesced_samples_all_reach_the_server(page):
    pick(page, "linen")
    sent = page.evaluate(
        """async () => {
            const s = document.querySelector('[data-testid=surface]');
            const r = document.querySelector('#picture').getBoundingClientRect();
            const init = (x, t) => ({pointerId: 7, pointerType: 'pen', isPrimary: true, bubbles: true, buttons: 1,
                                     clientX: r.left + x, clientY: r.top + 30, pressure: 0.4});
            const before = window.tactilize.samplesSent;
            // The page reads strokes from raw updates where the browser has them.
            const type = window.tactilize.inputMode;
            s.dispatchEvent(new PointerEvent('pointerdown', init(10)));
            const co = [11, 12, 13, 14].map((x) => new PointerEvent(type, init(x)));
            const ev = new PointerEvent(type, {...init(14), coalescedEvents: co});
            const n = ev.getCoalescedEvents().length;
            s.dispatchEvent(ev);
            s.dispatchEvent(new PointerEvent('pointerup', {...init(14), buttons: 0}));
            return {n, samples: window.tactilize.samplesSent - before};
        }"""
    )
    # 1 for pointerdown + every coalesced sample of the move (or the event itself
    # where the browser hands an empty list).
    assert sent["samples"] == 1 + max(1, sent["n"])
    assert sent["n"] in (0, 4)


def test_profile_picker_and_audio(page):
    pick(page, "corduroy")
    page.get_by_test_id("profile").select_option("physical")
    page.wait_for_function("window.tactilize.settings.profile === 'physical'")
    pen = Pen(page)
    box = surface_box(page)
    shown = pen.stroke(box["x"] + 10, box["y"] + 30, 30 / DEFAULT_MM_PER_PX, duration_s=0.3)
    pen.lift(pen.last_x, box["y"] + 30)
    # physical profile: f = v * f_s (~278 cycles/m at 30 mm/s: ~8.3 Hz)
    assert shown["frequency"] == pytest.approx(0.030 * 277.8, rel=0.25)
    # Audio is off until asked for, then the worklet runs.
    toggle = page.get_by_test_id("audio-toggle")
    assert toggle.get_attribute("aria-pressed") == "false"
    assert page.evaluate("window.tactilize.audio.ctx") is None
    toggle.click()
    page.wait_for_function("document.querySelector('[data-testid=audio-toggle]').getAttribute('aria-pressed') === 'true'", timeout=10_000)
    assert page.evaluate("window.tactilize.audio.ctx.state") == "running"
    assert page.evaluate("window.tactilize.audio.node !== null")
    toggle.click()
    page.wait_for_function("document.querySelector('[data-testid=audio-toggle]').getAttribute('aria-pressed') === 'false'")


def test_upload_through_the_page(page, tmp_path):
    from tactilize.data import png_bytes

    x = np.arange(300)
    stripes = (127 + 100 * np.cos(2 * np.pi * x / 12))[None, :].repeat(200, axis=0).astype(np.uint8)
    good = tmp_path / "stripes.png"
    good.write_bytes(png_bytes(stripes, 96.0))
    page.get_by_test_id("upload").set_input_files(str(good))
    page.locator("#upload-width").fill("60")
    page.locator("#upload-form button[type=submit]").click()
    page.wait_for_function("window.tactilize.texture && window.tactilize.texture.startsWith('upload-')", timeout=20_000)
    assert "60.0" in page.get_by_test_id("upload-status").text_content()
    assert page.get_by_test_id("texture-name").text_content() == "stripes.png"
    # Fig. 5 for it: the marked peak is what extract_features finds (25 cycles over 60 mm).
    from tactilize.features import extract_features
    from tactilize.image import load_image

    tid = page.evaluate("window.tactilize.texture")
    page.wait_for_function(f"document.querySelector('#spectrum-figure').dataset.id === '{tid}'", timeout=20_000)
    page.wait_for_function("document.querySelector('[data-testid=spectrum-fs]').textContent !== '–'", timeout=20_000)
    f_mm = extract_features(load_image(good.read_bytes(), width_mm=60.0)).spatial_frequency_per_m * 1e-3
    assert f_mm == pytest.approx(25 / 60, rel=0.02)
    assert float(page.get_by_test_id("spectrum-fs").text_content()) == pytest.approx(f_mm, abs=5e-4)
    bad = tmp_path / "notes.png"
    bad.write_bytes(b"this is not a picture")
    page.get_by_test_id("upload").set_input_files(str(bad))
    page.locator("#upload-form button[type=submit]").click()
    page.wait_for_function("document.querySelector('[data-testid=upload-status]').className === 'bad'", timeout=20_000)
    assert "not an image" in page.get_by_test_id("upload-status").text_content()


def test_the_page_shows_the_wire_state_and_hover_readies_it(page):
    pick(page, "corduroy")
    pen = Pen(page)
    box = surface_box(page)
    x, y = box["x"] + 40, box["y"] + 40
    # A pen hovering over the picture (no button): the server puts the wire in standby.
    # It hovers until the page says so (a hover is an event, not a duration).
    standby = "(window.tactilize.wireState || []).length === 2 && window.tactilize.wireState.every(s => s === 'standby')"
    deadline = time.monotonic() + 30.0
    i = 0
    while not page.evaluate(standby):
        assert time.monotonic() < deadline, "a hovering pen never put the wire in standby"
        pen._send("mouseMoved", x + 2 * (i % 10), y, 0, force=0.0)
        i += 1
    # A stroke: the wire vibrates, and the plot's legend says so in micrometres.
    # The wire warms before it vibrates, and a loaded machine is slow to: the pen
    # keeps moving until the page says so (a pen at rest would let it fall back).
    v = 40.0 / DEFAULT_MM_PER_PX
    pen.stroke(x, y + 20, v, duration_s=0.5)
    pen.keep_moving_until(y + 20, v, lambda: page.evaluate("(window.tactilize.wireState || []).includes('vibrating')"))
    pen.lift(pen.last_x, y + 20)
    page.wait_for_function("() => (window.tactilize.wireState || []).every(s => s === 'standby')", timeout=10_000)


def test_readouts_are_written_only_when_their_text_changes(page):
    # Every write to the document is a style, layout and paint: the wire trace
    # comes 20 times a second and the drive readouts 10, mostly unchanged.
    pick(page, "corduroy")
    page.wait_for_function("() => Array.isArray(window.tactilize.wireState)", timeout=10_000)
    page.evaluate(
        """() => { const c = (window.__writes = {wire: 0, direction: 0, surface: 0, traces: 0});
                   const watch = (sel, key, opts) => new MutationObserver((ms) => { c[key] += ms.length; })
                       .observe(document.querySelector(sel), opts);
                   watch('#wire-state', 'wire', {childList: true, characterData: true, subtree: true});
                   watch('#drive-direction', 'direction', {childList: true, characterData: true, subtree: true});
                   watch('#surface', 'surface', {attributes: true, attributeFilter: ['data-state']});
                   window.tactilize.ws.addEventListener('message', (ev) => { const t = JSON.parse(ev.data).type;
                       if (t === 'wire') c.traces++; else if (t === 'drive') c.drives = (c.drives || 0) + 1; });
                   window.__wireBefore = window.tactilize.wireState.join(); }"""
    )
    # Idle until the trace has come 5 times (20 a second: at least a quarter second).
    page.wait_for_function("window.__writes.traces >= 5", timeout=30_000)
    idle = page.evaluate("({...window.__writes, same: window.tactilize.wireState.join() === window.__wireBefore})")
    assert idle["same"] and idle["wire"] == 0
    # A steady stroke to the right: the direction reads 0 deg from its first drive
    # until the pen comes to rest ("–"), and the surface turns on once, however
    # many drives come back (the readouts follow them 10 times a second).
    # Every write is recorded with the text (or state) it left: a write that did not
    # change it shows as the same value twice in a row.  (A loaded machine may pause
    # the pen long enough for it to rest, "–", and move on: that is a change.)
    pen = Pen(page)
    box = surface_box(page)
    page.evaluate("""() => {
        const dir = document.querySelector('#drive-direction'), surf = document.querySelector('#surface');
        window.__shown = {direction: [dir.textContent], surface: [surf.dataset.state]};
        new MutationObserver((ms) => { for (const m of ms) {
            const t = m.type === 'characterData' ? m.target.data : Array.from(m.addedNodes).map((n) => n.textContent).join('');
            if (m.type === 'characterData' || m.addedNodes.length) window.__shown.direction.push(t); } })
            .observe(dir, {childList: true, characterData: true, subtree: true});
        new MutationObserver((ms) => { for (const m of ms) window.__shown.surface.push(m.oldValue); })
            .observe(surf, {attributes: true, attributeFilter: ['data-state'], attributeOldValue: true});
    }""")
    pen.stroke(box["x"] + 20, box["y"] + 60, 30.0 / DEFAULT_MM_PER_PX, duration_s=0.8)
    w = page.evaluate("window.__writes")
    shown = page.evaluate("({direction: window.__shown.direction, surface: window.__shown.surface.slice(1).concat([document.querySelector('#surface').dataset.state])})")
    pen.lift(pen.last_x, box["y"] + 60)
    assert w["drives"] >= 5
    # Moving right, the direction read 0 deg whenever the pen moved.
    assert "0" in shown["direction"] and set(shown["direction"]) <= {"0", "–"}
    # Each write changed what was shown: fewer writes than drives, none repeating.
    for key in ("direction", "surface"):
        seq = shown[key]
        assert all(a != b for a, b in zip(seq, seq[1:])), (key, seq)
    assert w["direction"] < w["drives"] and w["surface"] < w["drives"]
    assert "on" in shown["surface"]


def short_stroke_counted(page, server, n=60):
    """Press, ``n`` pen moves 4 ms apart, lift; returns (samples the page sent,
    samples the server received) over the stroke."""
    import httpx

    def received():
        return httpx.get(server + "api/stats").json()["counters"].get("samples_received", 0)

    pen = Pen(page)
    box = surface_box(page)
    x0, y = box["x"] + 10, box["y"] + 40
    before, sent0 = received(), page.evaluate("window.tactilize.samplesSent")
    pen._send("mousePressed", x0, y, 1)
    for i in range(1, n + 1):
        pen._send("mouseMoved", x0 + 1.5 * i, y, 1)
        time.sleep(0.004)
    pen.lift(x0 + 1.5 * n, y)
    page.wait_for_function("() => window.tactilize.lastDrive && !window.tactilize.lastDrive.down", timeout=5_000)
    return page.evaluate("window.tactilize.samplesSent") - sent0, received() - before


def test_raw_updates_are_used_and_each_sample_reaches_the_server_once(page, server):
    pick(page, "corduroy")
    # Chromium on loopback (a secure context) has pointerrawupdate: the page must use it.
    assert page.evaluate("'onpointerrawupdate' in window")
    assert page.evaluate("window.tactilize.inputMode") == "pointerrawupdate"
    assert page.get_by_test_id("input-mode").text_content() == "pointerrawupdate"
    page.evaluate(
        """() => { const c = (window.__count = {raw: 0, move: 0});
                   addEventListener('pointerrawupdate', () => c.raw++, true);
                   addEventListener('pointermove', () => c.move++, true); }"""
    )
    n = 60
    sent, received = short_stroke_counted(page, server, n)
    counts = page.evaluate("window.__count")
    # One sample for the press and one per pen event: raw updates, each once, however
    # many pointermove events the browser also fired for the same movement.
    assert counts["raw"] == n
    assert sent == n + 1
    assert received == sent
    # The live readout shows the last second's figures (numbers, whatever they are).
    page.wait_for_function("() => document.querySelector('[data-testid=latency-p99]').textContent !== '–'", timeout=5_000)
    assert float(page.get_by_test_id("latency-p50").text_content()) >= 0.0


def test_six_textures_side_by_side_follow_the_texture_under_the_pen(page):
    page.get_by_test_id("view-six").check()
    page.wait_for_function("window.tactilize.settings && window.tactilize.settings.composite", timeout=10_000)
    comp = page.evaluate("window.tactilize.settings.composite")
    assert len(comp["ids"]) == 6 and comp["cols"] == 3
    left_id, right_id = comp["ids"][0], comp["ids"][1]
    # Each at its physical size: the second picture starts one cell to the right.
    frame = page.locator("#frame").bounding_box()
    cell_px = comp["cell_mm"][0] / DEFAULT_MM_PER_PX
    assert frame["width"] == pytest.approx(3 * cell_px, abs=1.0)
    pen = Pen(page)
    y = frame["y"] + 40
    seq0 = page.evaluate("window.tactilize.seq")
    # 20 mm/s from 15 mm left of the boundary to 15 mm right of it.
    v = 20 / DEFAULT_MM_PER_PX
    x0 = frame["x"] + cell_px - 15 / DEFAULT_MM_PER_PX
    pen.stroke(x0, y, v, duration_s=1.5)
    shown_fs = float(page.get_by_test_id("texture-fs").text_content())
    pen.lift(pen.last_x, y)
    drives = page.evaluate(f"window.tactilize.drives.filter(d => d.seq > {seq0} && d.on)")
    edge_m = comp["cell_mm"][0] * 1e-3
    left = [d["spatial_frequency_per_m"] for d in drives if d["x_m"] < edge_m - 1e-3]
    right = [d["spatial_frequency_per_m"] for d in drives if d["x_m"] > edge_m + 1e-3]
    assert len(left) >= 3 and len(right) >= 3
    from tactilize.data import builtin_map

    f_left, f_right = builtin_map(left_id).whole.spatial_frequency_per_m, builtin_map(right_id).whole.spatial_frequency_per_m
    assert abs(f_right - f_left) > 0.5 * f_left  # two different textures
    assert np.median(left) == pytest.approx(f_left, rel=0.1)
    assert np.median(right) == pytest.approx(f_right, rel=0.1)
    # What the page showed with the pen on the second picture [cycles/mm].
    assert shown_fs == pytest.approx(f_right * 1e-3, rel=0.1)


def test_without_raw_updates_the_page_reads_pointermove_and_coalesced_samples_once(browser, server):
    # A browser without pointerrawupdate (Firefox, Safari, an insecure origin).
    no_raw = "delete Window.prototype.onpointerrawupdate; delete window.onpointerrawupdate;"
    with opened_page(browser, server, no_raw) as pg:
        assert not pg.evaluate("'onpointerrawupdate' in window")
        assert pg.evaluate("window.tactilize.inputMode") == "pointermove"
        pick(pg, "corduroy")
        n = 60
        sent, received = short_stroke_counted(pg, server, n)
    # Every pen event once, from the coalesced lists of frame-aligned pointermoves.
    assert sent == n + 1
    assert received == sent


def _pixels(page, selector):
    """The element as the user sees it: RGB array of a screenshot."""
    import io

    from PIL import Image

    return np.asarray(Image.open(io.BytesIO(page.locator(selector).screenshot())).convert("RGB")).astype(int)


def _is_red(im):
    return (im[..., 0] > 180) & (im[..., 1] < 90) & (im[..., 2] < 90)


def _red(im):
    """Pixels of the pen's trail."""
    return int(_is_red(im).sum())


def _blue(im):
    """Pixels of the plot's pulse train."""
    return int(((im[..., 2] > 200) & (im[..., 0] < 80)).sum())


def drawn(page):
    """(trail, plot) screenshots once both show a stroke (a trail and a pulse
    train), else None: the drawing runs at its own pace, in a worker."""
    trail, plot = _pixels(page, "#surface"), _pixels(page, "#plot")
    return (trail, plot) if _red(trail) > 100 and _blue(plot) > 20 else None


def until(check, timeout_s=30.0):
    """Poll ``check()`` until it is truthy (its value) or ``timeout_s`` passes (None)."""
    deadline = time.monotonic() + timeout_s
    while True:
        got = check()
        if got or time.monotonic() > deadline:
            return got or None


def test_the_plot_and_the_trail_are_drawn_off_the_main_thread(page):
    # Chromium has OffscreenCanvas and module workers: the page's drawing runs there.
    assert page.evaluate("window.tactilize.drawing") == "worker"
    assert page.get_by_test_id("drawing-mode").text_content() == "worker"
    pick(page, "corduroy")
    is_red, red, blue = _is_red, _red, _blue
    # The trail as the user sees it: inside the surface (the trail canvas spans the whole
    # map of copies, which the surface cuts; below it are the figures, Fig. 5's red marks too).
    assert red(_pixels(page, "#surface")) == 0
    pen = Pen(page)
    box = surface_box(page)
    x0, y = box["x"] + 10, box["y"] + 40
    v = 40.0 / DEFAULT_MM_PER_PX
    pen.stroke(x0, y, v, duration_s=0.8)
    # Still down and moving: the plot shows the pulse train of the drives that came
    # back, and the trail the stroke, once the drawing worker has drawn them (a
    # loaded machine may take a while: the pen keeps moving until it has).
    trail, plot = pen.keep_moving_until(y, v, lambda: drawn(page))
    pen.lift(pen.last_x, y)
    # The trail runs along the stroke, at its height, and nowhere else.
    rows = np.nonzero(is_red(trail).any(axis=1))[0]
    assert red(trail) > 100
    scale = trail.shape[1] / page.locator("#surface").bounding_box()["width"]
    assert abs(rows.mean() / scale - (y - page.locator("#surface").bounding_box()["y"])) < 4
    assert blue(plot) > 20
    # A new stroke clears the old trail (awaited: the worker clears it when it gets there).
    pen._send("mousePressed", x0, y + 60, 1)
    top = page.locator("#surface").bounding_box()["y"]

    def old_trail_gone():
        rows = np.nonzero(is_red(_pixels(page, "#surface")).any(axis=1))[0]
        return not (np.abs(rows / scale - (y - top)) < 4).any()

    assert until(old_trail_gone), "a new stroke left the old trail on the surface"
    pen.lift(x0, y + 60)


def test_without_offscreen_canvases_the_page_draws_on_its_own_thread(browser, server):
    # A browser without OffscreenCanvas (older Safari): the same drawing, in the page.
    with opened_page(browser, server, "delete HTMLCanvasElement.prototype.transferControlToOffscreen") as page:
        assert page.evaluate("window.tactilize.drawing") == "page"
        assert page.get_by_test_id("drawing-mode").text_content() == "page"
        pick(page, "corduroy")
        pen = Pen(page)
        box = surface_box(page)
        v = 40.0 / DEFAULT_MM_PER_PX
        pen.stroke(box["x"] + 10, box["y"] + 40, v, duration_s=0.8)
        trail, plot = pen.keep_moving_until(box["y"] + 40, v, lambda: drawn(page))
        pen.lift(pen.last_x, box["y"] + 40)
    assert _red(trail) > 100
    assert _blue(plot) > 20
