// A scrolling plot of the last WINDOW_S seconds: the pulse train of each channel
// (rebuilt here from the drives, phase-continuous, exactly as the audio and the
// controller play it) and the simulated wire's displacement sent by the server,
// in micrometres, with each wire's state (off, standby, warming, vibrating).

const WINDOW_S = 0.5;
// 30 redraws a second keep the plot fluid at half the cost of 60: it usually runs in
// the drawing worker (drawing.js), but on a two-core machine that worker shares the
// processors with the browser's network and the server.
const DRAW_INTERVAL_S = 1 / 30;
// The wire's trace follows a growing lag by at most this much per message [s] (messages
// come about every 20 ms, so up to 10 % of real time: a simulation falling behind is
// followed within a few messages), and re-aligns at once when the lag jumps by more
// than WIRE_RESYNC_S [s].
const WIRE_CATCH_UP_S = 0.002;
const WIRE_RESYNC_S = 0.25;
// In the page and in dedicated workers alike.
const nextFrame = typeof requestAnimationFrame === "function" ? (f) => requestAnimationFrame(f) : (f) => setTimeout(f, 16);

export class Plot {
  constructor(canvas, channels = 2) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.drives = Array.from({ length: channels }, () => ({ f: 0, w: 0, a: 0 }));
    this.next = new Array(channels).fill(null);       // time of the next pulse onset [s]
    this.pulses = Array.from({ length: channels }, () => []);  // [t_s, width_s, amp]
    this.wire = [];  // [t_s (local clock), displacement_um]
    this.wireOffset = null;
    this.wireState = [];  // per channel: off | standby | warming | vibrating
    this.running = true;
    this.dpr = 1;
    nextFrame(() => this.frame());
  }

  /** The plot's size on the page [CSS px] and the device pixel ratio: drawn at
   *  that resolution, its labels stay 11 CSS px high whatever the layout. */
  resize(wPx, hPx, dpr) {
    this.dpr = dpr;
    this.canvas.width = Math.max(1, Math.round(wPx * dpr));
    this.canvas.height = Math.max(1, Math.round(hPx * dpr));
    this.drawnAt = 0;
  }

  /** New drives: [{pulse_frequency_hz, pulse_width_s, amplitude}, ...]. */
  setDrives(channels) {
    channels.forEach((c, i) => {
      if (i >= this.drives.length) return;
      this.drives[i] = { f: c.pulse_frequency_hz || 0, w: c.pulse_width_s || 0, a: c.amplitude || 0 };
    });
  }

  /** Wire samples on the server's simulated clock, one array per channel, placed on
   *  the page's clock by the least lag seen: a message that came late (the network, a
   *  busy page) is drawn where its samples belong, not stretched back over the one
   *  before (each message re-aligned to "now" drew the trace backwards in places). */
  addWire(tS, dispUm, state) {
    if (Array.isArray(state)) this.wireState = state;
    if (!tS.length) return;
    const now = performance.now() / 1e3;
    const offset = now - tS[tS.length - 1];
    // A smaller offset is a message that came sooner: take it at once. A larger one is
    // late, or the simulation fell behind the page's clock: follow it slowly, and at
    // once after a jump (a new wire, a stall).
    if (this.wireOffset === null || offset < this.wireOffset || offset - this.wireOffset > WIRE_RESYNC_S) {
      this.wireOffset = offset;
    } else {
      this.wireOffset = Math.min(offset, this.wireOffset + WIRE_CATCH_UP_S);
    }
    const last = this.wire.length ? this.wire[this.wire.length - 1][0] : -Infinity;
    for (let i = 0; i < tS.length; i++) {
      const t = tS[i] + this.wireOffset;
      if (t > last) this.wire.push([t, dispUm.map((ch) => ch[i])]);  // never back in time
    }
    const from = now - WINDOW_S;
    while (this.wire.length && this.wire[0][0] < from) this.wire.shift();
  }

  frame() {
    if (!this.running) return;
    const now = performance.now() / 1e3;
    const from = now - WINDOW_S;
    this.drives.forEach((d, i) => {
      const list = this.pulses[i];
      if (d.f > 0 && d.w > 0 && d.a > 0) {
        if (this.next[i] === null || this.next[i] < from) this.next[i] = now;
        while (this.next[i] <= now) { list.push([this.next[i], d.w, d.a]); this.next[i] += 1 / d.f; }
      } else {
        this.next[i] = null;
      }
      while (list.length && list[0][0] < from) list.shift();
    });
    if (!(now - (this.drawnAt || 0) < DRAW_INTERVAL_S - 0.002)) {
      this.drawnAt = now;
      this.draw(now);
    }
    nextFrame(() => this.frame());
  }

  draw(now) {
    const { ctx, canvas, dpr } = this;
    const W = canvas.width, H = canvas.height;
    const lanes = this.drives.length + 1;
    const lh = H / lanes;
    const x = (t) => (t - (now - WINDOW_S)) / WINDOW_S * W;
    ctx.clearRect(0, 0, W, H);
    ctx.font = `${11 * dpr}px system-ui, sans-serif`;
    ctx.lineWidth = dpr;
    const label = 12 * dpr, pad = 4 * dpr, room = lh - 18 * dpr;
    this.pulses.forEach((list, i) => {
      const top = i * lh, base = top + lh - pad;
      ctx.fillStyle = "#888"; ctx.fillText(`channel ${i + 1} pulses`, pad, top + label);
      ctx.fillStyle = i ? "#c46a00" : "#1f6feb";
      for (const [t, w, a] of list) {
        const h = a * room;
        ctx.fillRect(x(t), base - h, Math.max(1, w / WINDOW_S * W), h);
      }
    });
    const top = (lanes - 1) * lh, base = top + lh - pad;
    // Autoscale to the window's range, but never finer than 1 um full scale: a
    // felt pulse moves the pin at least 0.5 um, so a still wire reads as flat.
    let lo = Infinity, hi = -Infinity;
    for (const [, ds] of this.wire) for (const d of ds) { lo = Math.min(lo, d); hi = Math.max(hi, d); }
    if (!(hi - lo > 1)) { const m = Number.isFinite(lo) ? (lo + hi) / 2 : 0; lo = m - 0.5; hi = m + 0.5; }
    ctx.fillStyle = "#888";
    const states = this.wireState.length ? ` (${this.wireState.join(" / ")})` : "";
    ctx.fillText(this.wire.length ? `wire ${lo.toFixed(1)} .. ${hi.toFixed(1)} µm${states}` : "wire displacement (no simulated wire on this output)", pad, top + label);
    const nch = this.wire.length ? this.wire[0][1].length : 0;
    for (let c = 0; c < nch; c++) {
      ctx.strokeStyle = c ? "#c46a00" : "#1f6feb"; ctx.beginPath();
      this.wire.forEach(([t, ds], k) => {
        const px = x(t), py = base - (ds[c] - lo) / (hi - lo) * room;
        k ? ctx.lineTo(px, py) : ctx.moveTo(px, py);
      });
      ctx.stroke();
    }
  }
}
