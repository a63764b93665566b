// <tactile-surface model="..." image="..." label="...">: a product photo that can be felt.
//
// One script tag on any page (docs/shop.md):
//   <script type="module" src="/tactile-surface.js"></script>
//   <tactile-surface model="linen.tsf" image="linen.jpg" label="Linen shirt"></tactile-surface>
//
// Everything runs here, in the page: the pen's samples (pen-input.js, coalesced samples),
// the surface rule (surface-rule.js, the JavaScript copy of tactilize.surface), and the
// outputs: the phone's motor (vibrate.js), the acceleration wavelets on Web Audio
// (pulse-worklet.js, headphones or a voice coil on the audio jack) and, where neither is
// on, a ring drawn at each bump.  Nothing is sent anywhere: the only requests are the
// model, the photo and the worklet module, all relative to this page or this module.
//
// A guest in someone else's page: the touch is taken only on the photo (touch-action there
// alone, so the page scrolls everywhere else), the motor and the sound start only from
// their own visible toggle (a tap is also the user activation browsers ask for), and
// every element is independent, so a grid of products works.

import { decodeModel, replayStroke, SurfaceRenderer, waveletRows } from "./surface-rule.js";
import { attachPen } from "./pen-input.js";
import { VibrationPulses, vibrationAvailable } from "./vibrate.js";

// Display metres per CSS pixel: the CSS reference pixel.  On phones a CSS pixel is nearer
// 0.16 mm (docs/references.md, section 5 (CSS pixel on phones)); that scales only the rule's
// lengths in metres (its 4 mm of history, its speed limits), not which bumps a stroke
// crosses nor when: those are set by the photo's pixels and the samples' times.
const CSS_PX_M = 0.0254 / 96;
// Wavelets play this long after the sample that placed them [s]: one audio render quantum
// and a little more, so a batch handled a few ms late moves nothing.
const LEAD_S = 0.010;
// A ring is drawn this long after each bump [ms].
const RING_MS = 140;

/** The bytes of base64 text (an ArrayBuffer). */
function bytesOfBase64(text) {
  const clean = text.replace(/\s+/g, "");
  if (typeof Uint8Array.fromBase64 === "function") return Uint8Array.fromBase64(clean).buffer;
  const bin = atob(clean), out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out.buffer;
}

let warmed = false;  // the rule has run once in this page

/** Run the rule once on a short made-up stroke, in a task of its own once a model is there:
 *  the engine compiles it then, not during the user's first stroke. */
function warmUp(model) {
  if (warmed) return;
  warmed = true;
  setTimeout(() => {
    const w = model.cols * CSS_PX_M, h = model.rows * CSS_PX_M;
    const samples = [];
    for (let i = 0; i < 24; i++) samples.push({ t: i / 240, x: w * (0.3 + 0.01 * i), y: h * 0.5, p: null });
    replayStroke(model, [CSS_PX_M, CSS_PX_M], samples);
  }, 0);
}

let audioShared = null;  // one AudioContext for every element of a page (browsers limit them)

/** Web Audio's worklet exists only in a secure context (HTTPS or this machine). */
function audioAvailable() {
  return typeof AudioContext === "function" && typeof AudioWorkletNode === "function" && window.isSecureContext !== false;
}

async function audioContext() {
  if (!audioShared) {
    audioShared = (async () => {
      const ctx = new AudioContext({ latencyHint: "interactive" });
      await ctx.audioWorklet.addModule(new URL("./pulse-worklet.js", import.meta.url));
      return ctx;
    })();
  }
  const ctx = await audioShared;
  await ctx.resume();
  return ctx;
}

const STYLE = `
:host { display: block; position: relative; font: 14px/1.3 system-ui, sans-serif; }
.pic { position: relative; touch-action: none; user-select: none; -webkit-user-select: none;
  -webkit-touch-callout: none; cursor: crosshair; line-height: 0; }
img { width: 100%; height: auto; display: block; pointer-events: none; border-radius: 4px; }
canvas { position: absolute; inset: 0; width: 100%; height: 100%; pointer-events: none; }
.bar { display: flex; gap: 6px; align-items: center; flex-wrap: wrap; margin-top: 6px; }
button { font: inherit; padding: 6px 10px; border-radius: 16px; border: 1px solid #667; background: #fff; color: #223; }
button[aria-pressed="true"] { background: #223; color: #fff; }
button:focus-visible { outline: 3px solid #38f; outline-offset: 2px; }
.hint { color: #556; font-size: 12px; }
`;

export class TactileSurface extends HTMLElement {
  static get observedAttributes() { return ["model", "image", "label"]; }

  constructor() {
    super();
    const root = this.attachShadow({ mode: "open" });
    root.innerHTML = `<style>${STYLE}</style><div class="pic" part="picture"><img alt=""><canvas></canvas></div>
      <div class="bar" part="controls"><button type="button" class="vib" aria-pressed="false" hidden>Vibrate: off</button>
      <button type="button" class="snd" aria-pressed="false" hidden>Sound: off</button>
      <span class="hint">Press and drag on the photo to feel it</span></div>`;
    this.pic = root.querySelector(".pic");
    this.img = root.querySelector("img");
    this.canvas = root.querySelector("canvas");
    this.hint = root.querySelector(".hint");
    this.model = null;
    this.modelPromise = null;
    this.renderer = null;
    this.pitch = null;
    this.queue = [];          // batches that came before the model
    this.rings = [];          // visual cue: {t_ms, x, y, s}
    this.vib = new VibrationPulses();
    this.audio = null;        // {ctx, node, offset, lastAt}
    this.stats = { batches: 0, latencyMs: [], workMs: [], leadMs: [], firstRenderMs: null, modelMs: null, events: 0 };
    this.handed = new Set();  // the stroke's events already handed to the outputs, by time [s]
    this._wire(root);
  }

  attributeChangedCallback(name, old, value) {
    if (name === "image") this.img.src = value || "";
    if (name === "label") this.img.alt = value || "";
    if (name === "model" && old !== null && old !== value) {
      // A new model: the one inlined in the page was the old one's.
      const inline = this.querySelector(':scope > script[type="application/octet-stream"]');
      if (inline) inline.remove();
      this.model = null; this.modelPromise = null; this._watch();
    }
  }

  connectedCallback() { this._watch(); }

  disconnectedCallback() {
    if (this.observer) this.observer.disconnect();
    this.vib.stop();
  }

  /** Load the model when the element comes near the screen (a long grid loads what is seen). */
  _watch() {
    if (this.observer) this.observer.disconnect();
    // In (or near) the first screen: now, not after the observer's first report (a frame later).
    const r = this.getBoundingClientRect();
    if (typeof IntersectionObserver !== "function" || r.top < innerHeight + 300) { this.load(); return; }
    this.observer = new IntersectionObserver((entries) => {
      if (entries.some((e) => e.isIntersecting)) { this.observer.disconnect(); this.load(); }
    }, { rootMargin: "300px" });
    this.observer.observe(this);
  }

  /** The surface model, decoded once (a promise): from the page itself when it holds it (a child
   *  <script type="application/octet-stream"> with the model file in base64), else fetched. */
  load() {
    const inline = this.modelPromise ? null : this.querySelector(':scope > script[type="application/octet-stream"]');
    if (inline) {
      // Decoded now, as the element is made: no fetch and no task between the page and the
      // heights, so the model is ready before the page's load event and a first stroke waits for nothing.
      try {
        this.model = decodeModel(bytesOfBase64(inline.textContent));
        this.stats.modelMs = performance.now();
        warmUp(this.model);
        this.modelPromise = Promise.resolve(this.model);
        return this.modelPromise;
      } catch (e) {
        this.hint.textContent = `Cannot feel this photo (${e.message})`;
        this.modelPromise = Promise.reject(e);
        this.modelPromise.catch(() => {});
        return this.modelPromise;
      }
    }
    if (!this.modelPromise && this.getAttribute("model")) {
      this.modelPromise = fetch(new URL(this.getAttribute("model"), document.baseURI))
        .then((r) => { if (!r.ok) throw new Error(`model: HTTP ${r.status}`); return r.arrayBuffer(); })
        .then(decodeModel)
        .then((m) => { this.model = m; this.stats.modelMs = performance.now(); warmUp(m); this._drain(); return m; })
        .catch((e) => { this.hint.textContent = `Cannot feel this photo (${e.message})`; throw e; });
      this.modelPromise.catch(() => {});
    }
    return this.modelPromise;
  }

  _wire(root) {
    const vibBtn = root.querySelector(".vib"), sndBtn = root.querySelector(".snd");
    if (vibrationAvailable()) vibBtn.hidden = false;
    if (audioAvailable()) sndBtn.hidden = false;
    vibBtn.addEventListener("click", () => {
      const on = vibBtn.getAttribute("aria-pressed") !== "true";
      vibBtn.setAttribute("aria-pressed", String(on));
      vibBtn.textContent = `Vibrate: ${on ? "on" : "off"}`;
      if (on) this.vib.start(); else this.vib.stop();
    });
    sndBtn.addEventListener("click", async () => {
      const on = sndBtn.getAttribute("aria-pressed") !== "true";
      sndBtn.setAttribute("aria-pressed", String(on));
      sndBtn.textContent = `Sound: ${on ? "on" : "off"}`;
      if (!on) { if (this.audio) this.audio.node.port.postMessage({ clear: true }); this.audio && (this.audio.on = false); return; }
      try {
        const ctx = await audioContext();
        if (!this.audio) {
          // The worklet's wavelet rule is the server's, written into the model file by Python.
          const node = new AudioWorkletNode(ctx, "tactilize-pulse", { numberOfInputs: 0, outputChannelCount: [2],
                                                                      processorOptions: { wavelet: this.model.header.rule.wavelet } });
          node.connect(ctx.destination);
          this.audio = { ctx, node, offset: null, lastAt: 0, on: true };
        }
        this.audio.on = true;
      } catch (e) {
        sndBtn.textContent = "Sound: unavailable";
      }
    });
    attachPen(this.pic, this.img, {
      onDown: () => this._down(),
      onBatch: (rows) => this._batch(rows),
      onLift: () => this._lift(),
    });
  }

  _down() {
    this.load();
    const r = this.img.getBoundingClientRect();
    this.rect = r;
    this.renderer = null;  // made with the display pitch of this stroke, when the model is there
    this.queue = [];
    this.handed.clear();
    if (this.audio) this.audio.offset = null;
    const dpr = window.devicePixelRatio || 1;
    this.canvas.width = Math.round(r.width * dpr);
    this.canvas.height = Math.round(r.height * dpr);
  }

  _batch(rows) {
    if (!this.model) { this.queue.push(rows); return; }
    this._render(rows);
  }

  _drain() {
    const q = this.queue;
    this.queue = [];
    for (const rows of q) this._render(rows);
  }

  _render(rows) {
    const entry = performance.now();
    const m = this.model;
    if (!this.renderer) {
      const w = this.rect.width * CSS_PX_M / m.cols, h = this.rect.height * CSS_PX_M / m.rows;
      this.renderer = new SurfaceRenderer(m, [w, h]);
    }
    // Samples in display metres from the photo's top-left, times in seconds of the page's clock.
    const batch = rows.map((r) => ({ t: r[0] / 1000, x: r[1] * CSS_PX_M, y: r[2] * CSS_PX_M, p: r[3] }));
    const events = this.renderer.feed(batch);
    const newest = rows[rows.length - 1];
    this._play(events, newest);
    const now = performance.now();
    const st = this.stats;
    st.batches++;
    st.events += events.length;
    if (st.firstRenderMs === null) st.firstRenderMs = now;
    // From the newest sample's own timestamp (the browser's dispatch included), and this element's work alone.
    st.latencyMs.push(now - newest[0]);
    st.workMs.push(now - entry);
    // What is felt: how long before its bump is crossed each event first reached the outputs
    // (the rule looks ahead along the stroke, so a delivered event is usually still to come).
    for (const e of events) if (!this.handed.has(e.t)) { this.handed.add(e.t); st.leadMs.push(e.t * 1000 - now); }
    if (st.latencyMs.length > 4000) { st.latencyMs.splice(0, 2000); st.workMs.splice(0, 2000); }
    if (st.leadMs.length > 4000) st.leadMs.splice(0, 2000);
  }

  /** Hand the events not yet fired to every output that is on; they replace what was handed before. */
  _play(events, newest) {
    const vibOn = this.vib.on, a = this.audio;
    if (vibOn) this.vib.playPulses(events.map((e) => ({ t_ms: e.t * 1000, strength: e.s })));
    if (a && a.on) {
      const nowS = newest[0] / 1000;
      // The stroke's clock on the context's, fixed for the stroke: a batch handled late moves nothing.
      if (a.offset === null) a.offset = a.ctx.currentTime + LEAD_S - nowS;
      a.lastAt = a.offset + nowS;
      a.node.port.postMessage({ channels: [{ f: 0 }, { f: 0 }],
        wavelets: waveletRows(events, nowS, this.model.header.rule.wavelet_band_hz), shares: [1, 1], at: a.lastAt });
    }
    if (!vibOn && !(a && a.on)) {
      // Neither a motor nor sound: a ring at each bump, where the pen is when it is crossed.
      const x = newest[1], y = newest[2];
      this.rings = this.rings.filter((g) => g.t_ms < newest[0]);
      for (const e of events) this.rings.push({ t_ms: e.t * 1000, x, y, s: e.s });
      if (!this.drawing) { this.drawing = true; requestAnimationFrame(() => this._draw()); }
    }
  }

  _draw() {
    const c = this.canvas, g = c.getContext("2d"), now = performance.now();
    const k = c.width / Math.max(1, this.rect ? this.rect.width : c.width);
    g.clearRect(0, 0, c.width, c.height);
    this.rings = this.rings.filter((r) => now - r.t_ms < RING_MS);
    for (const r of this.rings) {
      const age = (now - r.t_ms) / RING_MS;
      if (age < 0) continue;
      g.strokeStyle = `rgba(255,255,255,${(1 - age) * (0.35 + 0.65 * r.s)})`;
      g.lineWidth = 2 * k;
      g.beginPath();
      g.arc(r.x * k, r.y * k, (6 + 18 * age) * k, 0, 2 * Math.PI);
      g.stroke();
    }
    if (this.rings.length) requestAnimationFrame(() => this._draw());
    else this.drawing = false;
  }

  _lift() {
    if (this.renderer) this.renderer.lift();
    this.queue = [];
    // What was crossed has played; what lay ahead of the lifted pen never will.
    if (this.vib.on) { this.vib.stop(); this.vib.start(); }
    const a = this.audio;
    if (a && a.on && a.offset !== null) { a.node.port.postMessage({ channels: [{ f: 0 }, { f: 0 }], until: a.lastAt }); a.offset = null; }
  }
}

if (!customElements.get("tactile-surface")) customElements.define("tactile-surface", TactileSurface);
