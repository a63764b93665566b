// The tactile pen page: gallery, drawing surface, live drive, plot, calibration, audio.
// Plain ES modules, no build step.  The server does the tracking and the laws;
// this page only reports samples and shows (and plays) what comes back.

import { attachPen } from "./pen-input.js";
import { Plot } from "./plot.js";
import { AudioPulses } from "./audio.js";
import * as calibration from "./calibrate.js";
import * as strokeExport from "./stroke-export.js";

const $ = (sel) => document.querySelector(sel);
const HISTORY = 1000;

// Scripting handle (for users' scripts and the browser tests).
const T = (window.tactilize = {
  ws: null, texture: null, settings: null, lastDrive: null, drives: [], sent: 0, samplesSent: 0, seq: 0, errors: [],
  mmPerPx: calibration.mmPerPx(),
});

const plot = new Plot($("#plot"), 2);
const audio = (T.audio = new AudioPulses());
let textures = new Map();
let seq = 0;
let queue = [];     // messages to send once the socket is open
let retry = 250;    // reconnect backoff [ms]

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
  };
  ws.onmessage = (ev) => {
    let msg;
    try { msg = JSON.parse(ev.data); } catch (e) { return; }
    if (msg.type === "drive") onDrive(msg);
    else if (msg.type === "wire") { plot.addWire(msg.t_s, msg.displacement_um, msg.state); T.wireState = msg.state || null; }
    else if (msg.type === "ready" || msg.type === "state") onSettings(msg);
    else if (msg.type === "error") showError(msg.message);
  };
  ws.onclose = () => {
    setStatus("closed", "disconnected, retrying…");
    showDrive(null);
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
  if (msg.profile && $("#profile").value !== msg.profile) $("#profile").value = msg.profile;
  $("#output-name").textContent = msg.output || "";
  if (msg.texture) showPicture(msg.texture);
}

function showPicture(id) {
  const t = textures.get(id);
  if (!t) return;
  // The picture at its physical size: millimetres over calibrated mm per CSS px.
  const w = t.width_mm / T.mmPerPx, h = t.height_mm / T.mmPerPx;
  const img = $("#picture");
  if (img.dataset.id !== id) { img.src = t.url; img.dataset.id = id; }
  img.style.width = `${w}px`; img.style.height = `${h}px`;
  const trail = $("#trail"), dpr = window.devicePixelRatio || 1;
  trail.width = Math.round(w * dpr); trail.height = Math.round(h * dpr);
  trail.style.width = `${w}px`; trail.style.height = `${h}px`;
  const s = $("#surface");
  s.dataset.texture = id;
  s.dataset.mmPerPx = String(T.mmPerPx);
  $("#texture-name").textContent = t.name;
  $("#texture-size").textContent = ` ${t.width_mm.toFixed(1)} × ${t.height_mm.toFixed(1)} mm`;
  for (const b of document.querySelectorAll("#gallery button")) b.setAttribute("aria-pressed", String(b.dataset.id === id));
}

function selectTexture(id) {
  T.texture = id;
  showPicture(id);
  send({ type: "texture", id });
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
    cell("frequency").textContent = fmt(c.pulse_frequency_hz, 1);
    cell("pulse-width").textContent = fmt(c.pulse_width_s * 1e3, 3);
    cell("duty").textContent = fmt(c.duty_ratio * 100, 2);
    cell("amplitude").textContent = fmt(c.amplitude, 2);
    cell("clamped").textContent = (c.clamped || []).join(", ");
  }
  $("#drive-speed").textContent = fmt(msg ? msg.speed_mm_s : 0, 1);
  $("#drive-direction").textContent = msg && msg.direction_deg !== null && msg.direction_deg !== undefined ? msg.direction_deg.toFixed(0) : "–";
  $("#texture-fs").textContent = msg && msg.spatial_frequency_per_m !== null ? (msg.spatial_frequency_per_m / 1e3).toFixed(3) : "–";
  $("#texture-is").textContent = msg && msg.spectral_intensity !== null ? msg.spectral_intensity.toFixed(3) : "–";
  const on = !!(msg && msg.on);
  $("#surface").dataset.state = on ? "on" : "off";
  plot.setDrives(chans.length ? chans : [{}, {}]);
  audio.setDrives(chans.length ? chans : [{}, {}]);
}

function onDrive(msg) {
  T.lastDrive = msg;
  T.drives.push(msg);
  if (T.drives.length > HISTORY) T.drives.splice(0, T.drives.length - HISTORY);
  showDrive(msg);
}

// ------------------------------------------------------------------ trail

let last = null;
function drawTrail(rows, fresh) {
  const c = $("#trail"), ctx = c.getContext("2d"), dpr = window.devicePixelRatio || 1;
  if (fresh) { ctx.clearRect(0, 0, c.width, c.height); last = null; }
  ctx.strokeStyle = "rgba(220, 40, 40, 0.85)"; ctx.lineCap = "round";
  for (const [, x, y, p] of rows) {
    if (last) {
      ctx.lineWidth = (1 + 3 * (p === null ? 0.5 : p)) * dpr;
      ctx.beginPath(); ctx.moveTo(last[0] * dpr, last[1] * dpr); ctx.lineTo(x * dpr, y * dpr); ctx.stroke();
    }
    last = [x, y];
  }
}

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

async function setup() {
  const [config, profiles, list] = await Promise.all([loadJSON("/api/config"), loadJSON("/api/profiles"), loadJSON("/api/textures")]);
  T.config = config;
  const sel = $("#profile");
  for (const p of profiles.profiles) {
    const o = document.createElement("option"); o.value = p.name; o.textContent = p.name; o.title = p.description; sel.append(o);
  }
  sel.value = profiles.default;
  sel.addEventListener("change", () => send({ type: "profile", name: sel.value }));
  $("#output-name").textContent = config.output;
  list.forEach(addToGallery);
  calibrationNote();

  attachPen($("#surface"), $("#picture"), {
    onDown: () => {
      drawTrail([], true);
      const t = textures.get(T.texture);
      if (t) strokeExport.beginStroke(T.texture, T.mmPerPx, t.width_mm, t.height_mm);
    },
    onBatch: (rows) => {
      if (!T.texture) return;
      strokeExport.addSamples(rows);
      T.seq = ++seq;
      T.samplesSent += rows.length;
      send({ type: "samples", seq, samples: rows });
      drawTrail(rows, false);
    },
    onLift: () => {
      audio.setDrives([{}, {}]);  // silence now, not after the round trip
      T.seq = ++seq;
      send({ type: "lift", seq });
    },
    onHover: () => { if (T.texture) send({ type: "hover" }); },
  });

  calibration.setupDialog($("#calibration"), $("#calibrate"), (mm) => {
    T.mmPerPx = mm;
    calibrationNote();
    if (T.texture) showPicture(T.texture);
    send({ type: "calibrate", mm_per_px: mm });
  });

  $("#audio-toggle").addEventListener("click", async () => {
    const b = $("#audio-toggle");
    try {
      if (audio.on) { await audio.stop(); b.textContent = "Audio off"; b.setAttribute("aria-pressed", "false"); }
      else {
        await audio.start(); b.setAttribute("aria-pressed", "true");
        const l = audio.latencyS();
        b.textContent = `Audio on${l ? ` (${(l * 1e3).toFixed(0)} ms)` : ""}`;
      }
    } catch (e) { showError(`audio: ${e.message}`); }
  });

  $("#upload-form").addEventListener("submit", async (ev) => {
    ev.preventDefault();
    const file = $("#upload-file").files[0];
    const status = $("#upload-status");
    status.className = "";
    if (!file) { status.textContent = "choose a picture first"; status.className = "bad"; return; }
    const fd = new FormData(); fd.append("file", file); fd.append("width_mm", $("#upload-width").value);
    status.textContent = "analysing…";
    try {
      const r = await fetch("/api/textures", { method: "POST", body: fd });
      const body = await r.json();
      if (!r.ok) { status.textContent = body.error || `upload failed (${r.status})`; status.className = "bad"; return; }
      addToGallery(body);
      status.textContent = `${body.name}: ${body.width_mm.toFixed(1)} × ${body.height_mm.toFixed(1)} mm`;
      selectTexture(body.id);
    } catch (e) { status.textContent = `upload failed: ${e.message}`; status.className = "bad"; }
  });

  strokeExport.setupStrokeExport($("#stroke-export"), () => $("#profile").value);
  T.lastStroke = strokeExport.lastStroke;

  connect();
  if (list.length) selectTexture(list[0].id);
  document.body.dataset.ready = "true";
}

setup().catch((e) => { showError(`could not start: ${e.message}`); });
