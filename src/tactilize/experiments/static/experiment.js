// The participant's page: a thin view over the server's state machine.
// Every transition asks the server, which answers with the next state; the page
// never decides on its own where the session stands, so a reload, a second tab
// or a restarted server all land on the same, stored state.

import { attachPen, rowsInMm, samplesMessage } from "./pen-input.js";
import * as calibration from "./calibrate.js";
import { constants } from "./constants.js";

const api = new URL("api/", document.baseURI);
const $ = (id) => document.getElementById(id);
const views = ["welcome", "calibration", "trial", "break", "done"];
let session = localStorage.getItem("tactilize.session") || null;
let current = null;       // the last state document
let busy = false;         // one request at a time: no double submissions

function show(view) {
  for (const v of views) $("view-" + v).hidden = v !== view;
}

function message(text) {
  const m = $("message");
  m.textContent = text || "";
  m.hidden = !text;
}

async function call(method, path, body) {
  let res;
  try {
    res = await fetch(new URL(path, api), {
      method,
      headers: body ? { "Content-Type": "application/json" } : {},
      body: body ? JSON.stringify(body) : undefined,
    });
  } catch {
    // The browser's own text ("Failed to fetch") tells a participant nothing.
    throw new Error("The experiment server cannot be reached. Your answers on this page are kept; " +
                    "please wait a moment and try again, or call the experimenter.");
  }
  let doc = null;
  try { doc = await res.json(); } catch { doc = { error: `server answered ${res.status}` }; }
  if (!res.ok) {
    const err = new Error(doc.error || `error ${res.status}`);
    err.status = res.status;
    err.doc = doc;
    throw err;
  }
  return doc;
}

async function guarded(fn) {
  if (busy) return;
  busy = true;
  document.querySelectorAll("button").forEach((b) => (b.dataset.wasDisabled = b.disabled, b.disabled = true));
  try {
    await fn();
  } catch (err) {
    message(err.message);
    if (err.status === 409 && session) {
      // A stale page: show the stored state instead of what this page assumed.
      try { render(await call("GET", `sessions/${session}`), true); } catch { /* keep the message */ }
    }
    if (err.status === 404 && err.doc && err.doc.source === "session") {
      localStorage.removeItem("tactilize.session");
      session = null;
      show("welcome");
    }
  } finally {
    busy = false;
    document.querySelectorAll("button").forEach((b) => (b.disabled = b.dataset.wasDisabled === "true"));
    if (current && current.state === "trial") updateSubmit();
  }
}

// ---------------------------------------------------------------- state

function render(state, keepMessage = false) {
  current = state;
  if (!keepMessage) message("");
  // A visit moves on to its next protocol under a new session: the pen socket follows.
  if (session && state.session !== session) { closeSocket(); trial = null; }
  session = state.session;
  localStorage.setItem("tactilize.session", session);
  $("title").textContent = state.protocol.title;
  $("progress").textContent = `${state.participant} · ${state.progress.done} of ${state.progress.total} done`
    + (state.visit && state.visit.parts > 1 ? ` · part ${state.visit.part} of ${state.visit.parts}` : "");
  show(state.state);
  $("not-me").hidden = state.state === "done";
  document.body.dataset.state = state.state;
  if (state.state === "calibration") renderCalibration(state);
  if (state.state === "trial") renderTrial(state.trial);
  if (state.state === "done") { localStorage.removeItem("tactilize.session"); closeSocket(); }
}

// ---------------------------------------------------------------- welcome

async function welcome() {
  const info = await call("GET", "protocol");
  $("title").textContent = info.title;
  $("description").textContent = info.description;
  if (info.consent) $("consent-text").textContent = info.consent;  // the protocol's own information sheet
  buildDemographics(info.demographics || []);
  $("card-mm").textContent = info.calibration_card_mm;
  cardMm = info.calibration_card_mm;
  // The pen page's screen calibration, when this browser has one, pre-sets the card box.
  if (calibration.isCalibrated()) $("scale").value = String(Math.round(cardMm / calibration.mmPerPx()));
  $("scale").dispatchEvent(new Event("input"));
  if (session) {
    try { render(await call("GET", `sessions/${session}`)); return; } catch { localStorage.removeItem("tactilize.session"); session = null; }
  }
  show("welcome");
}

// Optional questions the protocol defines (age, handedness...): every one may be left empty.
function buildDemographics(items) {
  const box = $("demographics");
  box.replaceChildren();
  for (const d of items) {
    const lab = document.createElement("label");
    lab.className = "row";
    lab.textContent = `${d.text} (optional) `;
    let inp;
    if (d.kind === "integer") {
      inp = document.createElement("input");
      inp.type = "number"; inp.min = d.min; inp.max = d.max; inp.step = 1;
    } else {
      inp = document.createElement("select");
      for (const o of ["", ...d.options]) {
        const opt = document.createElement("option");
        opt.value = o; opt.textContent = o || "(prefer not to say)";
        inp.append(opt);
      }
    }
    inp.dataset.demographic = d.id;
    lab.append(inp);
    box.append(lab);
  }
}

function demographics() {
  const out = {};
  document.querySelectorAll("[data-demographic]").forEach((el) => { if (el.value !== "") out[el.dataset.demographic] = el.value; });
  return out;
}

$("start").addEventListener("click", () => guarded(async () => {
  render(await call("POST", "sessions", { participant_id: $("participant-id").value.trim(), consent: $("consent").checked,
                                          demographics: demographics() }));
}));
// "Not me": a shared computer may show the previous person's session; leave it
// without touching its data (the session stays resumable by its owner).
$("not-me").addEventListener("click", () => {
  closeSocket();
  localStorage.removeItem("tactilize.session");
  session = null; current = null; trial = null;
  document.body.dataset.state = "welcome";
  $("progress").textContent = "";
  $("participant-id").value = "";
  $("consent").checked = false;
  message("");
  show("welcome");
});

$("resume").addEventListener("click", () => guarded(async () => {
  // By ID only with the experimenter's token (this page opened with ?token=...):
  // an ID is guessable; the page itself resumes by its session token.
  const token = new URLSearchParams(location.search).get("token") || undefined;
  render(await call("POST", "resume", { participant_id: $("participant-id").value.trim(), token }));
}));

// ---------------------------------------------------------------- calibration

let mmPerPx = null;
let cardMm = calibration.CARD_MM[0];  // the protocol's card width [mm] once loaded

function renderCalibration(state) {
  const updateCard = () => ($("card").style.width = `${$("scale").value}px`);
  $("scale").oninput = updateCard;
  updateCard();
}

$("test-vibration").addEventListener("click", () => audio.pulse(150, 0.0004, 1.0, 0.6));
$("calibrate").addEventListener("click", () => guarded(async () => {
  render(await call("POST", `sessions/${session}/calibration`, {
    card_width_px: Number($("scale").value), felt: $("felt").checked,
  }));
}));

// ---------------------------------------------------------------- trial

let trial = null, image = null, strokeMs = 0, lastT = null, shownAt = 0;
let points = [], stroked = new Set();
let pictureShown = false;  // the picture on screen has loaded: pen input counts

function renderTrial(t) {
  const fresh = !trial || trial.index !== t.index;
  trial = t;
  mmPerPx = current.calibration ? current.calibration.mm_per_px : calibration.DEFAULT_MM_PER_PX;
  $("trial-title").textContent = t.practice ? `Practice trial ${t.number} (not counted)`
    : `Trial ${t.number} of ${current.progress.total}`;
  $("min-stroke").textContent = t.min_stroke_s;
  if (fresh) { strokeMs = 0; stroked = new Set(); shownAt = performance.now(); buildForm(t.questions); }
  const tabs = $("tabs");
  tabs.replaceChildren();
  t.images.forEach((im, i) => {
    const b = document.createElement("button");
    b.type = "button"; b.textContent = im.label; b.setAttribute("role", "tab");
    b.onclick = () => selectImage(im);
    b.dataset.image = im.id;
    tabs.append(b);
  });
  // Every picture of the trial is fetched now, while the server answers: a tab chosen
  // later (the server may be restarting by then) shows its picture from the cache.
  $("preload").replaceChildren(...t.images.map((im) => {
    const pre = document.createElement("img");
    pre.alt = ""; pre.src = new URL(im.url, api);
    return pre;
  }));
  selectImage(t.images[0]);
  openSocket();
  updateSubmit();
}

function selectImage(im) {
  image = im;
  document.querySelectorAll("#tabs button").forEach((b) => b.setAttribute("aria-selected", String(b.dataset.image === im.id)));
  const img = $("texture"), c = $("surface");
  // The box is laid out now, from the size the server sent, not when the picture
  // arrives: a box that grows on load moves the surface under a stroke begun before,
  // and its samples would be logged at the wrong picture mm.  True size: the
  // picture's mm over the calibrated mm per CSS px.
  const w = im.width_mm / mmPerPx, h = im.height_mm / mmPerPx;
  img.style.width = `${w}px`; img.style.height = `${h}px`;
  c.width = Math.round(w); c.height = Math.round(h);
  c.style.width = `${w}px`; c.style.height = `${h}px`;
  points = [];
  draw();
  // Until this picture is on screen the pen strokes nothing: its input is ignored.
  pictureShown = false;
  document.body.dataset.picture = "loading";
  img.onload = () => {
    if (image !== im) return;  // a tab chosen since: its own load decides
    pictureShown = true;
    document.body.dataset.picture = "shown";
  };
  img.onerror = () => { if (image === im) message("The picture could not be loaded: please reload the page."); };
  img.src = new URL(im.url, api);
}

function buildForm(questions) {
  const form = $("answers");
  form.replaceChildren();
  for (const q of questions) {
    const fs = document.createElement("fieldset");
    const lg = document.createElement("legend");
    lg.textContent = q.text;
    fs.append(lg);
    const scale = document.createElement("div");
    scale.className = "scale";
    for (let r = q.scale_min; r <= q.scale_max; r++) {
      const lab = document.createElement("label");
      const inp = document.createElement("input");
      inp.type = "radio"; inp.name = q.id; inp.value = String(r);
      inp.onchange = updateSubmit;
      lab.append(inp, document.createTextNode(String(r)));
      if (q.anchors[String(r)]) { const s = document.createElement("small"); s.textContent = q.anchors[String(r)]; lab.append(s); }
      scale.append(lab);
    }
    fs.append(scale);
    form.append(fs);
  }
  const lab = document.createElement("label");
  lab.className = "row";
  lab.textContent = "Comments (optional)";
  const ta = document.createElement("textarea");
  ta.id = "comment"; ta.maxLength = 2000; ta.rows = 2;
  lab.append(ta);
  form.append(lab);
}

function ratings() {
  const out = {};
  for (const q of trial.questions) {
    const sel = document.querySelector(`#answers input[name="${q.id}"]:checked`);
    if (sel) out[q.id] = Number(sel.value);
  }
  return out;
}

function updateSubmit() {
  if (!trial) return;
  const unstroked = trial.require_every_image ? trial.images.filter((im) => !stroked.has(im.id)) : [];
  const ready = strokeMs / 1000 >= trial.min_stroke_s && unstroked.length === 0;
  $("unstroked").textContent = unstroked.length ? `Still to stroke: ${unstroked.map((im) => im.label).join(", ")}.` : "";
  $("answers").hidden = !ready;
  $("stroke-time").textContent = (strokeMs / 1000).toFixed(1);
  // The rating waits until the pen is live and every sample is batched; a batch still
  // on its way when the answer goes is stored under its own trial all the same.
  $("submit").disabled = busy || !ready || !penLive() || queued() > 0
    || Object.keys(ratings()).length !== trial.questions.length;
}

// A 503 to an answer: the store cannot write now (a full disk, a database
// restarting).  The page keeps the answer and sends it again, waiting longer each
// time; its submission_id makes a resend that was stored after all harmless.
const ANSWER_RESEND_MS = 2000;
const ANSWER_RESEND_MAX_MS = 30000;

async function sendAnswer(body) {
  for (let wait = ANSWER_RESEND_MS; ; wait = Math.min(2 * wait, ANSWER_RESEND_MAX_MS)) {
    try {
      return await call("POST", `sessions/${session}/answers`, body);
    } catch (err) {
      if (err.status !== 503) throw err;
      message(`Your answer could not be saved yet; it is kept and sent again in ${Math.round(wait / 1000)} s.`);
      await new Promise((resolve) => setTimeout(resolve, wait));
    }
  }
}

$("submit").addEventListener("click", () => guarded(async () => {
  const doc = await sendAnswer({
    trial: trial.index, ratings: ratings(),
    response_time_s: (performance.now() - shownAt) / 1000,
    submission_id: `${session}:${trial.index}`,
    comment: $("comment") ? $("comment").value : "",
  });
  audio.stop();
  render(doc);
}));

$("end-break").addEventListener("click", () => guarded(async () => {
  render(await call("POST", `sessions/${session}/break`, { trial: current.next_trial }));
}));

// ---------------------------------------------------------------- pen
// No sample is lost to a restarted server or a dropped network.  Every sample is
// stamped with its trial and image when it is taken (not when it is sent).  Every
// 30 ms the samples taken since go out as one batch with an id of its own, and the
// page keeps the batch until the server acknowledges it, which it does only once the
// batch is committed to the database.  After a reconnect the page sends again every
// batch not yet acknowledged (and any left unacknowledged for RESEND_MS on a live
// socket); the id makes a resend harmless, the server stores each batch once.  The
// drive comes back at once, before the commit.  Meanwhile the socket reconnects with
// a growing delay, the page says the pen is not live and the rating waits, because
// the participant no longer feels the condition.

const FLUSH_MS = 30, RESEND_MS = 3000, WS_DELAY_MAX = 5000;
// An id for this page's batches: random, so two tabs or a reload never share one.
const pageId = Array.from(crypto.getRandomValues(new Uint8Array(8)), (b) => b.toString(16).padStart(2, "0")).join("");
let batchSeq = 0;

// One session's socket, its queue of samples and its batches not yet acknowledged.
class PenChannel {
  constructor(sess) {
    this.session = sess;
    this.ws = null; this.queue = []; this.pending = new Map();
    this.delay = 250; this.downSince = null; this.timer = null; this.retiring = false;
    this.open();
  }

  live() { return !!(this.ws && this.ws.readyState === 1); }

  open() {
    clearTimeout(this.timer);
    if (this.ws && this.ws.readyState <= 1) return;
    const u = new URL(`ws/${this.session}`, document.baseURI);
    u.protocol = u.protocol === "https:" ? "wss:" : "ws:";
    const sock = new WebSocket(u);
    this.ws = sock;
    sock.onopen = () => {
      this.delay = 250;
      if (this.downSince !== null && trial && !this.retiring) {
        // Tell the server this trial's stream had a gap; it marks the trial interrupted.
        sock.send(JSON.stringify({ type: "reconnected", trial: trial.index,
                                   gap_s: (performance.now() - this.downSince) / 1000,
                                   queued: this.queue.length + this.pendingSamples() }));
      }
      this.downSince = null;
      this.flush(true);
      penStatus();
    };
    sock.onmessage = (ev) => this.receive(JSON.parse(ev.data));
    sock.onclose = () => {
      if (this.ws !== sock) return;
      this.ws = null;
      if (!this.retiring) audio.set(null);  // nothing drives the pen now: do not leave the last drive playing
      if (this.downSince === null) this.downSince = performance.now();
      penStatus();
      if (this.closed) return;
      this.timer = setTimeout(() => this.open(), this.delay);
      this.delay = Math.min(WS_DELAY_MAX, this.delay * 2);
      document.body.dataset.wsRetries = String(Number(document.body.dataset.wsRetries || 0) + 1);
    };
  }

  receive(msg) {
    if (msg.type === "ack" || (msg.type === "error" && msg.batch && !msg.retry)) {
      // Stored (or refused for good: resending would not change the answer).
      this.pending.delete(msg.batch);
      document.body.dataset.unacked = String(this.pending.size);
      if (this.retiring && !this.pending.size && !this.queue.length) this.close();
    }
    if (this.retiring) return;
    if (msg.type === "drive") { audio.set(msg.drive); document.body.dataset.lastDriveHz = msg.drive.pulse_frequency_hz; }
    else if (msg.type === "error" && !msg.retry) message(msg.error);
    document.body.dataset.wsMessages = String(Number(document.body.dataset.wsMessages || 0) + 1);
  }

  pendingSamples() { let n = 0; for (const b of this.pending.values()) n += b.n; return n; }

  // Batch what was queued (consecutive samples of one trial and image, at most the
  // server's max_batch each), then send what is due: every pending batch after a reconnect (all), else
  // the new ones and those left unacknowledged for RESEND_MS.
  flush(all = false) {
    while (this.queue.length) {
      const head = this.queue[0];
      let n = 0;
      while (n < this.queue.length && n < constants.max_batch && this.queue[n].trial === head.trial
             && this.queue[n].image === head.image) n++;
      const id = `${pageId}-${++batchSeq}`;
      const text = JSON.stringify(samplesMessage(id, this.queue.slice(0, n).map((q) => q.s),
                                                 { trial: head.trial, image: head.image }));
      this.pending.set(id, { text, n, sentAt: null });
      this.queue = this.queue.slice(n);
    }
    document.body.dataset.unacked = String(this.pending.size);
    if (!this.live()) return;
    const now = performance.now();
    for (const b of this.pending.values()) {
      if (all || b.sentAt === null || now - b.sentAt > RESEND_MS) { this.ws.send(b.text); b.sentAt = now; }
    }
  }

  send(obj) { if (this.live()) this.ws.send(JSON.stringify(obj)); }

  // The page moves to another session (or none): keep this one's socket until every
  // batch is acknowledged, then close it.
  retire() {
    this.retiring = true;
    this.flush();
    if (!this.pending.size) this.close();
  }

  close() {
    this.closed = true;
    clearTimeout(this.timer);
    if (this.ws) { const s = this.ws; this.ws = null; s.close(); }
  }
}

let pen = null;            // the channel of the session on screen
const retired = new Set(); // channels of earlier sessions still draining

function penLive() { return !!(pen && pen.live()); }

function penStatus() {
  const live = penLive();
  document.body.dataset.pen = live ? "live" : "down";
  $("pen-status").hidden = live || !pen;
  if (current && current.state === "trial") updateSubmit();
}

function openSocket() {
  if (pen && pen.session === session) { pen.open(); return; }
  if (pen) closeSocket();
  pen = new PenChannel(session);
}

function closeSocket() {
  if (pen) {
    const old = pen;
    pen = null;
    old.retire();
    if (!old.closed) retired.add(old);
  }
  penStatus();
}

function queued() { return pen ? pen.queue.length : 0; }

function flush() {
  if (pen) pen.flush();
  for (const ch of retired) { if (ch.closed) retired.delete(ch); else ch.flush(); }
  if (current && current.state === "trial") updateSubmit();
}
setInterval(flush, FLUSH_MS);

// The pen page's pointer handling (raw updates or coalesced samples, each sample once,
// with its own timestamp), stamped here with the trial and image it was taken in.
const surface = $("surface");
const up = () => {
  lastT = null; audio.set(null);
  flush();
  // The actuator stops the moment the pen leaves the surface.
  if (pen) pen.send({ type: "lift" });
};
attachPen(surface, surface, {
  onDown: (ev) => { lastT = ev.timeStamp; points = []; },
  onBatch: (rows) => {
    if (!pen || !trial || !image || !pictureShown) return;
    const mm = rowsInMm(rows, mmPerPx);
    rows.forEach((r, k) => {
      pen.queue.push({ trial: trial.index, image: image.id, s: mm[k] });
      points.push([r[1], r[2]]);
      if (lastT !== null && r[0] - lastT < 200) strokeMs += r[0] - lastT;
      lastT = r[0];
    });
    stroked.add(image.id);
    draw();
    updateSubmit();
  },
  onLift: up,
});

function draw() {
  const ctx = surface.getContext("2d");
  ctx.clearRect(0, 0, surface.width, surface.height);
  ctx.strokeStyle = "rgba(229, 57, 53, .8)"; ctx.lineWidth = 2; ctx.beginPath();
  points.slice(-400).forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
  ctx.stroke();
}

// ---------------------------------------------------------------- audio actuator
// A voice-coil or LRA actuator on the headphone output plays the pulse train.
// Inside the pen app (`tactilize experiment run`) the pen page's AudioWorklet
// pulse synthesiser is reused; served alone, a square oscillator whose frequency
// follows the drive stands in for it.

let pulses = null;
import("/static/audio.js").then((m) => { pulses = new m.AudioPulses(); }).catch(() => { pulses = null; });

const OFF = { pulse_frequency_hz: 0, pulse_width_s: 0, amplitude: 0 };

const audio = {
  ctx: null, osc: null, gain: null,
  ensure() {
    if (this.ctx) return true;
    const AC = window.AudioContext || window.webkitAudioContext;
    if (!AC) return false;
    this.ctx = new AC();
    this.gain = this.ctx.createGain(); this.gain.gain.value = 0; this.gain.connect(this.ctx.destination);
    this.osc = this.ctx.createOscillator(); this.osc.type = "square"; this.osc.connect(this.gain); this.osc.start();
    return true;
  },
  set(drive) {
    if (pulses) {
      if (pulses.on) pulses.setDrives([drive || OFF, drive || OFF]);
      return;
    }
    if (!this.ensure()) return;
    const on = drive && drive.pulse_frequency_hz > 0 && drive.amplitude > 0;
    const now = this.ctx.currentTime;
    if (on) this.osc.frequency.setTargetAtTime(drive.pulse_frequency_hz, now, 0.005);
    this.gain.gain.setTargetAtTime(on ? 0.25 * drive.amplitude : 0, now, 0.005);
  },
  async pulse(hz, width, amp, seconds) {
    // A click is the user gesture browsers require before audio may start.
    if (pulses && !pulses.on) { try { await pulses.start(); } catch { pulses = null; } }
    this.set({ pulse_frequency_hz: hz, pulse_width_s: width, amplitude: amp });
    setTimeout(() => this.set(null), seconds * 1000);
  },
  stop() { this.set(null); },
};

welcome().catch((err) => message(err.message));
