// The tactile pen page: gallery, drawing surface, live drive, plot, calibration, audio.
// Plain ES modules, no build step.  The server does the tracking and the laws;
// this page only reports samples and shows (and plays) what comes back.

import { attachPen, INPUT, rowsInMm, samplesMessage } from "./pen-input.js";
import { constants } from "./constants.js";
import { startDrawing } from "./drawing.js";
import { LatencyMeter } from "./latency.js";
import { showSpectrum, redrawSpectrum } from "./spectrum.js";
import { AudioPulses, audioAvailable } from "./audio.js";
import { VibrationPulses, vibrationAvailable } from "./vibrate.js";
import * as calibration from "./calibrate.js";
import * as strokeExport from "./stroke-export.js";
import { onOutputMessage } from "./output-lease.js";

const $ = (sel) => document.querySelector(sel);
// A readout is written only when its text changes: every write is a style,
// layout and paint of the page, and readouts follow a pen 10 .. 20 times a second.
// A readout's one text node is rewritten in place: replacing it (textContent) made
// the node leave and rejoin the layout tree, a style recalculation the next pen
// event's hit test had to do first; rewritten, only its text is laid out again.
const setText = (el, text) => {
  const node = el.firstChild;
  if (node && node === el.lastChild && node.nodeType === Node.TEXT_NODE) { if (node.data !== text) node.data = text; }
  else if (el.textContent !== text) el.textContent = text;
};
const HISTORY = 1000;

// Scripting handle (for users' scripts and the browser tests).
const T = (window.tactilize = {
  ws: null, texture: null, settings: null, lastDrive: null, drives: [], sent: 0, samplesSent: 0, seq: 0, errors: [],
  mmPerPx: calibration.mmPerPx(),
  inputMode: INPUT, latency: { last: null }, view: "single", six: [], composite: null, wireState: null,
});

const draw = startDrawing($("#plot"), $("#trail"), 2, (text) => showError(text));
T.drawing = draw.mode;
const audio = (T.audio = new AudioPulses());
const vibration = (T.vibration = new VibrationPulses());
let textures = new Map();
let seq = 0;
let queue = [];     // messages to send once the socket is open
let retry = 250;    // reconnect backoff [ms]
let lastSurfaceMsg = null;  // the texture or composite message the server has
const meter = new LatencyMeter();
// The plot's width over its height (style.css gives it the same aspect-ratio).
const PLOT_ASPECT = 3;
const SIX_COLS = 3;
const MAX_REPEAT = constants.max_repeat;

// ------------------------------------------------------------------ socket

function connect() {
  const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`;
  const ws = new WebSocket(url);
  T.ws = ws;
  setStatus("connecting", "connecting…");
  ws.onopen = () => {
    retry = 250;
    setStatus("open", "connected");
    const hello = { type: "hello", mm_per_px: T.mmPerPx };
    if (T.texture) hello.texture = T.texture;
    const p = $("#profile").value; if (p) hello.profile = p;
    ws.send(JSON.stringify(hello));
    for (const m of queue) ws.send(m);
    queue = [];
    lastSurfaceMsg = null;
    applySurface();
  };
  ws.onmessage = (ev) => {
    let msg;
    try { msg = JSON.parse(ev.data); } catch (e) { return; }
    if (msg.type === "drive") onDrive(msg);
    else if (msg.type === "wire") {
      draw.addWire(msg);
      T.wireState = msg.state || null;
      setText($("#wire-state"), T.wireState ? T.wireState.join(" / ") : "–");
    }
    else if (msg.type === "ready" || msg.type === "state") onSettings(msg);
    else if (msg.type === "error") showError(msg.message);
    else if (msg.type === "output") onOutputMessage(msg, send);
  };
  ws.onclose = () => {
    setStatus("closed", "disconnected, retrying…");
    showDrive(null);
    vibration.setDrives([{}, {}]);
    draw.setDrives([{}, {}]);
    setTimeout(connect, retry);
    retry = Math.min(5000, retry * 2);
  };
}

function send(obj) {
  const text = JSON.stringify(obj);
  if (T.ws && T.ws.readyState === WebSocket.OPEN) { T.ws.send(text); T.sent++; }
  else if (obj.type !== "samples") queue.push(text);  // stale samples are worthless later
}

function setStatus(state, text) { const s = $("#status"); s.dataset.state = state; s.textContent = text; }

let errorTimer = null;
function showError(text) {
  T.errors.push(text);
  const e = $("#error"); e.textContent = text;
  clearTimeout(errorTimer); errorTimer = setTimeout(() => { e.textContent = ""; }, 6000);
}

// ------------------------------------------------------------------ settings

function onSettings(msg) {
  T.settings = msg;
  T.composite = msg.composite || null;
  if (msg.profile && $("#profile").value !== msg.profile) $("#profile").value = msg.profile;
  $("#output-name").textContent = msg.output || "";
}

// The stroking surface: one picture at its physical size (repeated to fill the
// stage when "fill the screen" is on), or six side by side (the paper's Fig. 16).
// Sample positions are from #frame's top-left: the first picture's corner.

/** The stroking area [CSS px]: the stage's width, and the height that leaves in
 *  the first screen what follows the surface: the pulse plot on a wide page (Fig. 5
 *  may be below the fold), the drive readouts on a phone (style.css puts them
 *  right under the surface there). */
function stageSize() {
  const s = $("#surface");
  const w = s.clientWidth || 600;
  const top = s.getBoundingClientRect().top + window.scrollY;
  const phone = getComputedStyle($("#stage")).display === "contents";
  // The figures under the picture (the wire's plot, and Fig. 5 beside it on a wide screen) stay on the first screen.
  const below = (phone ? $("#drive-group") : $("#figures")).getBoundingClientRect().height || 0;
  const h = Math.max(phone ? 160 : 200, window.innerHeight - top - below - (phone ? 12 : 24));
  return [w, h];
}

/** The width the surface may take [CSS px]: its layout parent's content box (the
 *  stage, or on a phone, where the stage gives its parts to main, main). */
function availableWidth() {
  let p = $("#surface").parentElement;
  while (p && getComputedStyle(p).display === "contents") p = p.parentElement;
  if (!p) return 600;
  const cs = getComputedStyle(p);
  return p.clientWidth - parseFloat(cs.paddingLeft) - parseFloat(cs.paddingRight);
}

function place(img, t, x, y, w, h) {
  if (img.dataset.id !== t.id) { img.src = t.url; img.dataset.id = t.id; }
  img.alt = t.name;
  Object.assign(img.style, { left: `${x}px`, top: `${y}px`, width: `${w}px`, height: `${h}px` });
}

/** Lay the surface out; returns the message the server needs for it (or null). */
function layoutSurface() {
  const mm = T.mmPerPx, tiles = $("#tiles");
  let cells = [], cols = 1, cw = 0, ch = 0, msg = null;
  let visW = null, visH = null;  // the part of the surface shown [CSS px], when it is cut
  if (T.view === "six") {
    const list = T.six.map((id) => textures.get(id)).filter(Boolean);
    if (!list.length) return null;
    cw = Math.max(...list.map((t) => t.width_mm)) / mm; ch = Math.max(...list.map((t) => t.height_mm)) / mm;
    // Three across as in the paper where they fit (a quarter of a cell may be cut);
    // fewer on a narrow screen, where a third column would be out of reach.
    cols = Math.max(1, Math.min(SIX_COLS, Math.floor((availableWidth() + 0.25 * cw) / cw)));
    cells = list.map((t, i) => [t, (i % cols) * cw, Math.floor(i / cols) * ch]);
    msg = { type: "composite", ids: list.map((t) => t.id), cols };
    $("#texture-name").textContent = "Six textures side by side";
    $("#texture-size").textContent = ` ${cols} × ${Math.ceil(list.length / cols)} cells of ${(cw * mm).toFixed(1)} × ${(ch * mm).toFixed(1)} mm (Fig. 16)`;
  } else {
    const t = textures.get(T.texture);
    if (!t) return null;
    cw = t.width_mm / mm; ch = t.height_mm / mm;
    let rows = 1;
    if ($("#fill").checked) {
      // Whole copies past the stage's edges, cut by the surface: the surface is the
      // stage's full width (and the height left for it) whatever the picture's size.
      [visW, visH] = stageSize();
      cols = Math.max(1, Math.ceil(visW / cw)); rows = Math.max(1, Math.ceil(visH / ch));
      while (cols * rows > MAX_REPEAT) rows > 1 ? rows-- : cols--;
      visW = Math.min(visW, cols * cw); visH = Math.min(visH, rows * ch);
    }
    for (let r = 0; r < rows; r++) for (let c = 0; c < cols; c++) cells.push([t, c * cw, r * ch]);
    msg = { type: "texture", id: t.id };
    if (cols * rows > 1) msg.repeat = [cols, rows];
    $("#texture-name").textContent = t.name;
    $("#texture-size").textContent = ` ${t.width_mm.toFixed(1)} × ${t.height_mm.toFixed(1)} mm` + (cols * rows > 1 ? `, repeated ${cols} × ${rows}` : "");
  }
  const rows = Math.ceil(cells.length / cols);
  const W = cols * cw, H = rows * ch;
  place($("#picture"), cells[0][0], 0, 0, cells[0][0].width_mm / mm, cells[0][0].height_mm / mm);
  while (tiles.children.length < cells.length - 1) { const im = document.createElement("img"); im.draggable = false; tiles.append(im); }
  while (tiles.children.length > cells.length - 1) tiles.lastChild.remove();
  cells.slice(1).forEach(([t, x, y], i) => place(tiles.children[i], t, x, y, t.width_mm / mm, t.height_mm / mm));
  const frame = $("#frame"), trail = $("#trail"), dpr = window.devicePixelRatio || 1;
  frame.style.width = `${W}px`; frame.style.height = `${H}px`;
  draw.trailResize(W, H, dpr);
  const pw = $("#plot").clientWidth;
  if (pw) draw.plotResize(pw, pw / PLOT_ASPECT, dpr);
  trail.style.width = `${W}px`; trail.style.height = `${H}px`;
  const s = $("#surface");
  s.style.width = visW === null ? `${W}px` : "";
  s.style.height = visH === null ? "" : `${visH}px`;
  T.visible = { w: visW === null ? W : visW, h: visH === null ? H : visH, mapW: W, mapH: H };
  s.dataset.view = T.view;
  s.dataset.texture = T.view === "six" ? "" : T.texture;
  s.dataset.mmPerPx = String(mm);
  T.cell = { w: cw, h: ch, cols, ids: cells.map((c) => c[0].id) };
  const shown = T.view === "six" ? null : textures.get(T.texture);
  for (const b of document.querySelectorAll("#gallery button")) {
    b.setAttribute("aria-pressed", String(T.view === "six" ? T.six.includes(b.dataset.id) : b.dataset.id === (shown ? shown.base || shown.id : T.texture)));
  }
  showRenderedAs();
  return msg;
}

/** Lay out and tell the server, unless it already has this surface. */
function applySurface() {
  const msg = layoutSurface();
  if (!msg) return;
  const text = JSON.stringify(msg);
  if (text !== lastSurfaceMsg && T.ws && T.ws.readyState === WebSocket.OPEN) { lastSurfaceMsg = text; send(msg); }
  spectrumFor(T.view === "six" ? T.six[0] : T.texture);
}

function spectrumFor(id) {
  const t = textures.get(id);
  if (!t || $("#spectrum-figure").dataset.id === id) return;
  showSpectrum(t).catch((e) => showError(e.message));
}

function selectTexture(id) {
  if (T.view === "six") {
    // Put it in the next slot (cycling), so built-ins and uploads can be mixed.
    if (!T.six.includes(id)) { T.six[T.sixNext % T.six.length] = id; T.sixNext++; }
    applySurface();
    return Promise.resolve();
  }
  // The picture as the picker's material: the server builds its surface with it.
  return renderedAs(id, $("#material").value).then((rid) => {
    if (rid !== T.texture) strokeExport.forget();  // the last stroke was on another picture
    T.texture = rid;
    applySurface();
  }).catch((e) => showError(e.message));
}

/** The id of picture ``id`` rendered as material ``name`` ("" picture only): the entry
 *  itself when it already is, else the server's rendering of it (made on first ask). */
async function renderedAs(id, name) {
  const t = textures.get(id);
  if (!t || (t.material || "") === name) return id;
  const base = textures.get(t.base) || t;
  if ((base.material || "") === name) return base.id;
  const r = await fetch(`/api/textures/${encodeURIComponent(base.id)}/rendered`, {
    method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify({ material: name }) });
  const body = await r.json();
  if (!r.ok) throw new Error(body.error || `rendering failed (${r.status})`);
  textures.set(body.id, body);
  return body.id;
}

/** The line saying what the shown picture is rendered as. */
function showRenderedAs() {
  const t = T.view === "six" ? null : textures.get(T.texture);
  const text = t ? `rendered as: ${t.rendered_as}` : "rendered as: each picture's own (six side by side)";
  const el = $("#rendered-as");
  setText(el, text);
  el.dataset.material = t ? (t.material || "") : "";
}

function setView(view) {
  T.view = view;
  strokeExport.forget();
  $("#gallery-hint").textContent = view === "six" ? "Click a texture to put it in the next of the six places." : "Pick the picture to stroke.";
  applySurface();
}

/** Samples as the server's map has them: a point past the cut edge of a filled
 *  surface is moved past the map's edge by as much, so leaving what is shown is
 *  leaving the picture (and the drive stops), as with one copy. */
function toMap(rows) {
  const v = T.visible;
  if (!v || (v.w >= v.mapW && v.h >= v.mapH)) return rows;
  return rows.map((r) => {
    if (r[1] < v.w && r[2] < v.h) return r;
    const q = r.slice();
    if (q[1] >= v.w) q[1] += v.mapW - v.w;
    if (q[2] >= v.h) q[2] += v.mapH - v.h;
    return q;
  });
}

function calibrationNote() {
  $("#calibration-note").textContent = `${T.mmPerPx.toFixed(4)} mm per CSS px` + (calibration.isCalibrated() ? " (calibrated)" : " (not calibrated: 1/96 inch)");
}

// ------------------------------------------------------------------ drive

const fmt = (x, d) => (Number.isFinite(x) ? x.toFixed(d) : "0");

function showDrive(msg) {
  const chans = msg ? msg.channels : [];
  const sfx = ["", "-ch2"];
  for (let i = 0; i < 2; i++) {
    const c = chans[i] || { pulse_frequency_hz: 0, pulse_width_s: 0, duty_ratio: 0, amplitude: 0, clamped: [] };
    const cell = (name) => document.querySelector(`[data-testid="drive-${name}${sfx[i]}"]`);
    setText(cell("frequency"), fmt(c.pulse_frequency_hz, 1));
    setText(cell("pulse-width"), fmt(c.pulse_width_s * 1e3, 3));
    setText(cell("duty"), fmt(c.duty_ratio * 100, 2));
    setText(cell("amplitude"), fmt(c.amplitude, 2));
    setText(cell("clamped"), (c.clamped || []).join(", "));
  }
  setText($("#drive-speed"), fmt(msg ? msg.speed_mm_s : 0, 1));
  setText($("#drive-direction"), msg && msg.direction_deg !== null && msg.direction_deg !== undefined ? msg.direction_deg.toFixed(0) : "–");
  setText($("#texture-fs"), msg && msg.spatial_frequency_per_m !== null ? (msg.spatial_frequency_per_m / 1e3).toFixed(3) : "–");
  setText($("#texture-is"), msg && msg.spectral_intensity !== null ? msg.spectral_intensity.toFixed(3) : "–");
  const on = (shownOn = !!(msg && msg.on));
  const surface = $("#surface");
  if (surface.dataset.state !== (on ? "on" : "off")) surface.dataset.state = on ? "on" : "off";
  // The surface rendering fires a pulse per bump crossed (docs/surfaces.md): its
  // frequency is the local rate of those pulses, and the page counts them.
  if (msg && msg.rendering && surface.dataset.rendering !== msg.rendering) surface.dataset.rendering = msg.rendering;
  if (T.pulses) surface.dataset.pulses = String(T.pulses);
  audio.setDrives(chans.length ? chans : [{}, {}]);
}

function onDrive(msg) {
  // The batch ids this page chooses are its count of batches: `seq` is the newest one covered.
  msg.seq = msg.batch === null || msg.batch === undefined ? null : Number(msg.batch);
  if (!msg.resting && typeof msg.seq === "number") meter.drive(msg.seq);
  msg.page_ms = performance.now();  // when it arrived, in the page's clock (outputs and tests line up on it)
  T.lastDrive = msg;
  if (msg.pulses) T.pulses = (T.pulses || 0) + msg.pulses;
  // A faulty sense path, a stopped simulation.  Written only when it changes: setting
  // `hidden` again, even to the same value, is an attribute change the page's style
  // is recalculated for, once a drive (250 times a second) and before the next pen event.
  const faultText = msg.output_fault || "";
  if (faultText !== shownFault) {
    shownFault = faultText;
    const fault = $("#output-fault");
    fault.hidden = !faultText;
    fault.textContent = faultText;
  }
  T.drives.push(msg);
  if (T.drives.length > HISTORY) T.drives.splice(0, T.drives.length - HISTORY);
  const chans = msg.channels && msg.channels.length ? msg.channels : [{}, {}];
  audio.setDrives(chans, msg);  // the sound, the motor and the plot follow at once
  vibration.setDrives(msg.on && !msg.resting ? chans : [{}, {}]);
  draw.setDrives(chans);
  // The readouts of a moving pen change READOUT_MS apart, not once a batch: numbers
  // changing faster cannot be read, and each change costs the main thread a layout
  // and a paint that a drive arriving meanwhile waits for.  A start or stop shows at once.
  if (!msg.on || !shownOn) { clearTimeout(showTimer); showTimer = 0; showNow(msg); return; }
  if (!showTimer) showTimer = setTimeout(() => { showTimer = 0; showNow(T.lastDrive); }, Math.max(0, shownAt + READOUT_MS - performance.now()));
}
const READOUT_MS = 100;
let shownFault = "";  // the #output-fault text shown (the page starts with it hidden and empty)
let showTimer = 0, shownAt = -Infinity;
let shownOn = false;
function showNow(msg) { shownAt = performance.now(); showDrive(msg); }

// ------------------------------------------------------------------ setup

async function loadJSON(url) {
  const r = await fetch(url);
  if (!r.ok) throw new Error(`${url}: ${r.status}`);
  return r.json();
}

function addToGallery(t) {
  textures.set(t.id, t);
  if (document.querySelector(`#gallery button[data-id="${CSS.escape(t.id)}"]`)) return;
  const li = document.createElement("li");
  const b = document.createElement("button");
  b.type = "button"; b.dataset.testid = "texture"; b.setAttribute("data-testid", "texture"); b.dataset.id = t.id;
  b.setAttribute("aria-pressed", "false");
  const f = t.features || {};
  b.title = `${t.description}\n${t.width_mm.toFixed(1)} × ${t.height_mm.toFixed(1)} mm, ` +
    `f_s ${(f.spatial_frequency_per_m || 0).toFixed(0)} cycles/m, i_s ${(f.spectral_intensity || 0).toFixed(3)}`;
  const img = document.createElement("img"); img.src = t.url; img.alt = t.name; img.loading = "lazy";
  const cap = document.createElement("span"); cap.textContent = t.name;
  b.append(img, cap);
  b.addEventListener("click", () => selectTexture(t.id));
  li.append(b);
  $("#gallery").append(li);
}

// ------------------------------------------------------------------ outputs on the page

/** The audio button says its state: off, starting, on (with the browser's latency),
 *  or why it cannot be on (the AudioWorklet needs a secure context: HTTPS or loopback). */
function setupAudioToggle(b) {
  const say = (state, text) => { b.dataset.state = state; b.textContent = text; b.setAttribute("aria-pressed", String(state === "on")); };
  if (!audioAvailable()) {
    say("unavailable", "Audio: needs HTTPS");
    b.disabled = true;
    b.title = "The audio output (an AudioWorklet) needs a secure context: serve with --https, or open the page on this machine";
    return;
  }
  say("off", "Audio: off");
  b.addEventListener("click", async () => {
    try {
      if (audio.on) { await audio.stop(); say("off", "Audio: off"); }
      else {
        say("starting", "Audio: starting…");
        await audio.start();
        const l = audio.latencyS();
        say("on", `Audio: on${l ? ` (${(l * 1e3).toFixed(0)} ms)` : ""}`);
      }
    } catch (e) { say("off", "Audio: off"); showError(`audio: ${e.message}`); }
  });
}

/** The phone's own motor, where the browser has the Vibration API and a touch
 *  screen: off until tapped (the API wants a user gesture, and a motor should not
 *  start by surprise). */
function setupVibrationToggle(b) {
  if (!vibrationAvailable()) return;
  b.hidden = false;
  const say = (on) => { b.dataset.state = on ? "on" : "off"; b.textContent = on ? "Vibrate: on" : "Vibrate: off"; b.setAttribute("aria-pressed", String(on)); };
  say(false);
  b.addEventListener("click", () => {
    if (vibration.on) vibration.stop(); else vibration.start();
    say(vibration.on);
  });
}

/** On a touch screen not yet calibrated, say so over the surface: a phone's CSS
 *  pixel is far from 1/96 inch, so its textures show too large until then. */
function setupCalibrationPrompt() {
  const box = $("#calibrate-prompt");
  const later = "tactilize.calibration.later";
  if (calibration.isCalibrated() || !calibration.likelyPhone() || sessionStorage.getItem(later)) return;
  box.hidden = false;
  $("#calibrate-now").addEventListener("click", () => { box.hidden = true; $("#calibrate").click(); });
  $("#calibrate-later").addEventListener("click", () => { box.hidden = true; sessionStorage.setItem(later, "1"); applySurface(); });
}

async function setup() {
  const [config, profiles, list, materials] = await Promise.all([loadJSON("/api/config"), loadJSON("/api/profiles"),
    loadJSON("/api/textures"), loadJSON("/api/materials")]);
  T.config = config;
  const picker = $("#material");
  for (const m of materials.materials) {
    const o = document.createElement("option"); o.value = m.name; o.textContent = m.name; o.title = `${m.description}: ${m.rendered_as}`;
    picker.append(o);
  }
  picker.value = materials.default || "";
  // A new material re-renders the shown picture (uploads and later choices take it too).
  picker.addEventListener("change", () => { if (T.texture && T.view !== "six") selectTexture(T.texture); });
  const sel = $("#profile");
  for (const p of profiles.profiles) {
    const o = document.createElement("option"); o.value = p.name; o.textContent = p.name; o.title = p.description; sel.append(o);
  }
  sel.value = profiles.default;
  sel.addEventListener("change", () => send({ type: "profile", name: sel.value }));
  $("#output-name").textContent = config.output;
  list.forEach(addToGallery);
  calibrationNote();

  attachPen($("#surface"), $("#frame"), {
    onDown: (ev) => {
      draw.trailClear();
      $("#surface-hint").hidden = true;
      // Six side by side: Fig. 5 follows the picture the stroke starts on.
      if (T.view === "six" && T.cell) {
        const r = $("#frame").getBoundingClientRect();
        const i = Math.floor((ev.clientY - r.top) / T.cell.h) * T.cell.cols + Math.floor((ev.clientX - r.left) / T.cell.w);
        if (i >= 0 && i < T.cell.ids.length) spectrumFor(T.cell.ids[i]);
      }
      // The stroke export records strokes on one picture, on any of its copies.
      const t = T.view !== "six" ? textures.get(T.texture) : null;
      const v = T.visible || { w: 0, h: 0 };
      if (t) strokeExport.beginStroke(T.texture, T.mmPerPx, t.width_mm, t.height_mm, v.w * T.mmPerPx, v.h * T.mmPerPx);
      else strokeExport.forget();
    },
    onBatch: (rows) => {
      if (!T.texture && T.view !== "six") return;
      if (T.view !== "six") strokeExport.addSamples(rows);
      T.seq = ++seq;
      T.samplesSent += rows.length;
      send(samplesMessage(seq, rowsInMm(toMap(rows), T.mmPerPx)));
      meter.sent(seq, rows[rows.length - 1][0]);
      draw.trailAdd(rows);
    },
    onLift: () => {
      audio.setDrives([{}, {}]);  // silence now, not after the round trip
      vibration.setDrives([{}, {}]);
      T.seq = ++seq;
      send({ type: "lift", batch: String(seq) });
    },
    onHover: () => { if (T.texture) send({ type: "hover" }); },
  });

  calibration.setupDialog($("#calibration"), $("#calibrate"), (mm) => {
    T.mmPerPx = mm;
    $("#calibrate-prompt").hidden = true;
    calibrationNote();
    send({ type: "calibrate", mm_per_px: mm });
    applySurface();
  });

  setupAudioToggle($("#audio-toggle"));
  setupVibrationToggle($("#vibrate-toggle"));
  setupCalibrationPrompt();

  $("#upload-form").addEventListener("submit", async (ev) => {
    ev.preventDefault();
    const file = $("#upload-file").files[0];
    const status = $("#upload-status");
    status.className = "";
    if (!file) { status.textContent = "choose a picture first"; status.className = "bad"; return; }
    const fd = new FormData(); fd.append("file", file); fd.append("width_mm", $("#upload-width").value);
    fd.append("material", $("#material").value);
    status.textContent = "analysing…";
    try {
      const r = await fetch("/api/textures", { method: "POST", body: fd });
      const body = await r.json();
      if (!r.ok) { status.textContent = body.error || `upload failed (${r.status})`; status.className = "bad"; return; }
      addToGallery(body);
      status.textContent = `${body.name}: ${body.width_mm.toFixed(1)} × ${body.height_mm.toFixed(1)} mm`;
      await selectTexture(body.id);
    } catch (e) { status.textContent = `upload failed: ${e.message}`; status.className = "bad"; }
  });

  $("#input-mode").textContent = INPUT;
  $("#drawing-mode").textContent = draw.mode;
  setInterval(() => {
    const st = (T.latency.last = meter.stats());
    setText($("#latency-p50"), st ? st.p50.toFixed(1) : "–");
    setText($("#latency-p99"), st ? st.p99.toFixed(1) : "–");
  }, 250);
  for (const r of document.querySelectorAll('input[name="view"]')) r.addEventListener("change", () => r.checked && setView(r.value));
  $("#fill").addEventListener("change", applySurface);
  let resizeTimer = null;
  window.addEventListener("resize", () => {
    clearTimeout(resizeTimer);
    resizeTimer = setTimeout(() => { applySurface(); redrawSpectrum(); }, 150);
  });
  T.six = list.filter((t) => t.builtin).slice(0, 6).map((t) => t.id);
  T.sixNext = 0;
  if (list.length) T.texture = list[0].id;
  strokeExport.setupStrokeExport($("#stroke-export"), () => $("#profile").value);
  T.lastStroke = strokeExport.lastStroke;

  connect();
  applySurface();
  document.body.dataset.ready = "true";
}

setup().catch((e) => { showError(`could not start: ${e.message}`); });
