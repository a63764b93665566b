// The surface rendering's rule in the browser: a pulse event per bump the pen crosses.
//
// The JavaScript copy of what tactilize.surface and tactilize.pen run in Python
// (docs/surfaces.md, "What is rendered" and "Along the stroke, in real time"):
// the tracker's least-squares velocity (pen/tracker.py), the path on a grid fixed
// in arc length and its window from 4 mm behind the pen to the look-ahead
// (surface/path.py), the heights by bilinear lookup and the bumps by prominence
// (surface/_kernels.py), and the stroke's bookkeeping: too late, already played,
// strengths, clusters, rate only (surface/_stroke_kernels.py, surface/stroke.py).
// Every parameter comes from the model file, written by Python
// (tactilize.site.model_file), so the two cannot drift apart silently;
// tests/test_site_parity.py runs both on the same strokes in headless Chromium.
// Arithmetic follows the Python order step by step, so heights and times agree
// to rounding, not just to a tolerance.
//
// Units: SI (s, m), as in Python; positions in display metres, y down.

const MAGIC = 0x31465354; // "TSF1" read as a little-endian uint32

/** Decode a model file (an ArrayBuffer): {header, cols, rows, field (Float32Array, padded by
 *  one edge pixel all round, as SurfaceModel.lookup_table)}. */
export async function parseModel(buffer) {
  const view = new DataView(buffer);
  if (buffer.byteLength < 8 || view.getUint32(0, true) !== MAGIC) throw new Error("not a tactilize surface model");
  const n = view.getUint32(4, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 8, n)));
  // The heights are a zlib stream: the browser's own inflater, no library.
  const stream = new Blob([new Uint8Array(buffer, 8 + n)]).stream().pipeThrough(new DecompressionStream("deflate"));
  const r = new Uint8Array(await new Response(stream).arrayBuffer());
  const { cols, rows } = header;
  if (r.length !== cols * rows) throw new Error("damaged surface model");
  const q = new Uint8Array(cols * rows);
  const grad = header.predictor === "gradient";
  for (let y = 0; y < rows; y++) {
    const o = y * cols;
    for (let x = 0; x < cols; x++) {
      let p = 0;
      if (x > 0) p = grad && y > 0 ? q[o + x - 1] + q[o - cols + x] - q[o - cols + x - 1] : q[o + x - 1];
      else if (grad && y > 0) p = q[o - cols];
      q[o + x] = (p + r[o + x]) & 0xff;
    }
  }
  // Height = offset + q * scale in float64, then float32: what Python's ModelFile.heights does.
  const pc = cols + 2, field = new Float32Array(pc * (rows + 2));
  for (let y = -1; y <= rows; y++) {
    const sy = Math.min(rows - 1, Math.max(0, y));
    for (let x = -1; x <= cols; x++) {
      const sx = Math.min(cols - 1, Math.max(0, x));
      field[(y + 1) * pc + x + 1] = header.offset + q[sy * cols + sx] * header.scale;
    }
  }
  return { header, cols, rows, field, levels: q };
}

/** Map coordinates' bilinear lookup (order 1, mode "nearest") at row cy, column cx of the padded field. */
function bilinear(field, R, C, cy, cx) {
  cy = cy < 0 ? 0 : (cy > R - 1 ? R - 1 : cy);
  cx = cx < 0 ? 0 : (cx > C - 1 ? C - 1 : cx);
  const fy = Math.floor(cy), fx = Math.floor(cx);
  const r0 = fy, c0 = fx;
  const wy0 = 1 - (cy - fy), wy1 = 1 - wy0, wx0 = 1 - (cx - fx), wx1 = 1 - wx0;
  const r1 = r0 + 1 < R ? r0 + 1 : Math.max(R - 2, 0);
  const c1 = c0 + 1 < C ? c0 + 1 : Math.max(C - 2, 0);
  let t = 0;
  t += (field[r0 * C + c0] * wy0) * wx0;
  t += (field[r0 * C + c1] * wy0) * wx1;
  t += (field[r1 * C + c0] * wy1) * wx0;
  t += (field[r1 * C + c1] * wy1) * wx1;
  return t;
}

/** Bumps of h[a:b] as scipy.signal.find_peaks(prominence=floor) finds them: [index - a, prominence]. */
function peaks(h, a, b, floor, outIdx, outProm) {
  let i = a + 1;
  const last = b - 1;
  while (i < last) {
    if (h[i - 1] < h[i]) {
      let ahead = i + 1;
      while (ahead < last && h[ahead] === h[i]) ahead++;
      if (h[ahead] < h[i]) {
        const peak = Math.floor((i + ahead - 1) / 2);  // a plateau's middle, rounded down
        const top = h[peak];
        let leftMin = top, j = peak;
        while (j >= a && h[j] <= top) { if (h[j] < leftMin) leftMin = h[j]; j--; }
        let rightMin = top;
        j = peak;
        while (j < b && h[j] <= top) { if (h[j] < rightMin) rightMin = h[j]; j++; }
        const prom = top - Math.max(leftMin, rightMin);
        if (floor <= prom) { outIdx.push(peak - a); outProm.push(prom); }
        i = ahead;
      }
    }
    i++;
  }
}

/** Sum in order, as the tracker's fit in Python does (a plain sum on Python 3.11; 3.12 compensates,
 *  which moves the fit by rounding only). */
function fsum(xs) {
  let f = 0;
  for (const x of xs) f += x;
  return f;
}

/** The stroke tracker: velocity as the least-squares slope over the last window (pen/tracker.py). */
export class Tracker {
  constructor(p) { this.p = p; this.buf = []; this.cand = null; this.state = null; this.dirty = false; }

  reset() { this.buf = []; this.cand = null; this.state = null; this.dirty = false; }

  _start(s) {
    this.buf = [s]; this.cand = null; this.dirty = false;
    this.state = { t: s.t, x: s.x, y: s.y, speed: 0, direction: null, pressure: s.p };
  }

  _append(s) {
    this.buf.push(s);
    if (this.buf.length > this.p.max_samples) this.buf.shift();
    this.dirty = true;
  }

  static _speed(a, b) {
    const dt = b.t - a.t;
    return dt <= 0 ? Infinity : Math.hypot(b.x - a.x, b.y - a.y) / dt;
  }

  add(s) {
    if (!(Number.isFinite(s.t) && Number.isFinite(s.x) && Number.isFinite(s.y))) return;
    const p = this.p, buf = this.buf;
    if (!buf.length) { this._start(s); return; }
    const cand = this.cand, last = cand || buf[buf.length - 1];
    const dt = s.t - last.t;
    if (dt <= 0) {
      if (dt < -p.max_gap_s && !(dt === 0)) this._start(s);
      return;
    }
    if (dt > p.max_gap_s) { this._start(s); return; }
    if (cand) {
      this.cand = null;
      if (Tracker._speed(cand, s) <= p.max_speed_m_s) { this._start(cand); this._append(s); return; }
      if (s.t <= buf[buf.length - 1].t) return;
      if (buf[buf.length - 1].t < s.t - p.max_gap_s) { this._start(s); return; }
    }
    if (Tracker._speed(buf[buf.length - 1], s) > p.max_speed_m_s) { this.cand = s; return; }
    this._append(s);
  }

  get estimate() {
    if (this.dirty) { this.dirty = false; this.state = this._fit(); }
    return this.state;
  }

  _windowStart() {
    const p = this.p, buf = this.buf, n = buf.length, newest = buf[n - 1];
    const from = newest.t - p.window_s;
    let start = 0;
    while (start < n && buf[start].t < from) start++;  // bisect_left
    start = Math.max(0, Math.min(start, n - p.min_samples));
    while (start > 0 && buf[start - 1].t >= newest.t - p.max_window_s) {
      const first = buf[start];
      if (Math.abs(newest.x - first.x) + Math.abs(newest.y - first.y) >= p.min_travel_m) break;
      start--;
    }
    return start;
  }

  _fit() {
    const buf = this.buf, newest = buf[buf.length - 1];
    const w = buf.slice(this._windowStart());
    const m = w.length;
    const ts = w.map((s) => s.t - newest.t);
    const tm = fsum(ts.map((t) => t)) / m;
    const dts = ts.map((t) => t - tm);
    const dot = (a, b) => fsum(a.map((v, i) => v * b[i]));
    const stt = dot(dts, dts);
    let vx = 0, vy = 0;
    if (stt > 0) {
      vx = dot(dts, w.map((s) => s.x - newest.x)) / stt;
      vy = dot(dts, w.map((s) => s.y - newest.y)) / stt;
    }
    const speed = Math.hypot(vx, vy);
    const direction = speed > this.p.still_speed_m_s ? Math.atan2(-vy, vx) : null;
    return { t: newest.t, x: newest.x, y: newest.y, speed, direction, pressure: newest.p };
  }
}

const RATE_ONLY = 1, CLUSTER = 2, MERGED = 4, LATE = 8;

/** One stroke's pulse events over a model, batch by batch (surface/stroke.py's SurfaceStroke). */
export class SurfaceStroke {
  /** displayPitch: [x, y] display metres per model pixel, where the picture is shown. */
  constructor(model, displayPitch) {
    const h = model.header, r = h.rule;
    this.model = model;
    this.r = r;
    this.inv = [1 / displayPitch[0], 1 / displayPitch[1]];
    const spd = h.surface_pitch_m[0] / displayPitch[0];
    // SurfaceModel.step_m: a quarter of the tip radius, never coarser than half a pixel.
    this.step = Math.min(0.25 * h.tip_radius_m / spd, 0.5 * Math.min(displayPitch[0], displayPitch[1]));
    this.same = r.same_bump_share * (h.tip_radius_m / Math.max(spd, 1e-12));
    this.floor = h.prominence_floor;
    this.reset();
  }

  reset() {
    this.last = null;       // [t, x, y, arc] of the newest sample
    this.k0 = 0;            // grid index of pts[0]
    this.pt = []; this.px = []; this.py = []; this.ph = [];  // points: time, x, y, height (NaN off the picture)
    this.known = 0;         // points whose heights are looked up
    this.ring = [];         // fired: {t, s, f, arc}, the newest fired_kept
    this.nfired = 0;
    this.pend = [];
    this.lastFired = NaN;
    this.now = null;
    this.newlyFired = 0;
  }

  _addPoint(t, x, y) {
    const last = this.last;
    if (last === null) {
      this.last = [t, x, y, 0];
      this.k0 = 0; this.pt = [t]; this.px = [x]; this.py = [y]; this.ph = []; this.known = 0;
      return;
    }
    const [t0, x0, y0, s0] = last;
    const d = Math.hypot(x - x0, y - y0);
    if (d <= 0) { this.last = [t, x, y, s0]; return; }
    const s1 = s0 + d;
    this.last = [t, x, y, s1];
    const step = this.step;
    const kEnd = Math.floor(s1 / step);
    let k = Math.floor(s0 / step) + 1;
    const lo = Math.ceil((s1 - this.r.history_m) / step);
    if (lo > k) { k = lo; this.k0 = lo; this.pt = []; this.px = []; this.py = []; this.ph = []; this.known = 0; }
    if (k > kEnd) return;
    if (!this.pt.length) this.k0 = k;
    const dt = (t - t0) / d, dx = (x - x0) / d, dy = (y - y0) / d;
    for (let kk = k; kk <= kEnd; kk++) {
      const a = kk * step - s0;
      this.pt.push(t0 + a * dt); this.px.push(x0 + a * dx); this.py.push(y0 + a * dy);
    }
  }

  _height(x, y) {
    const m = this.model, px = x * this.inv[0], py = y * this.inv[1];
    if (px >= 0 && px < m.cols && py >= 0 && py < m.rows) return bilinear(m.field, m.rows + 2, m.cols + 2, py + 0.5, px + 0.5);
    return NaN;
  }

  /** A batch [{t, x, y, p}] with the tracker's speed [m/s] and direction [rad, y up] (null: still).
   *  Returns the events not yet fired [{t, s, f}] (t on the stroke's clock [s]). */
  update(samples, speed, direction, pressure) {
    const r = this.r;
    for (const smp of samples) {
      if (!(Number.isFinite(smp.t) && Number.isFinite(smp.x) && Number.isFinite(smp.y))) continue;
      if (this.last !== null) {
        const dt = smp.t - this.last[0];
        if (dt <= 0) continue;
        if (dt > r.max_gap_s) this.reset();
      }
      this._addPoint(smp.t, smp.x, smp.y);
    }
    if (this.last === null) return [];
    const now = this.last[0];
    const previous = this.now;
    this.now = now;
    this.newlyFired = 0;
    // What was handed out and is due by now has fired.
    for (const e of this.pend) {
      if (e.t <= now) {
        this.ring.push(e);
        if (this.ring.length > r.fired_kept) this.ring.shift();
        this.nfired++; this.newlyFired++;
        if (Number.isNaN(this.lastFired) || e.t > this.lastFired) this.lastFired = e.t;
      }
    }
    this.pend = [];
    const moving = direction !== null && speed > r.still_speed_m_s;
    const step = this.step;
    const [t0, x0, y0, s0] = this.last;
    // Drop the points no window reaches again, then the window from history_m behind.
    const first = Math.ceil((s0 - r.history_m) / step);
    const drop = Math.min(this.known, Math.max(0, first - this.k0));
    if (drop > 0) {
      this.pt.splice(0, drop); this.px.splice(0, drop); this.py.splice(0, drop); this.ph.splice(0, drop);
      this.k0 += drop; this.known -= drop;
    }
    const end = this.pt.length;
    for (let i = this.known; i < end; i++) this.ph[i] = this._height(this.px[i], this.py[i]);
    this.known = end;
    const a = Math.min(end, Math.max(0, first - this.k0));
    const h = this.ph.slice(a, end), times = this.pt.slice(a, end);
    if (moving) {
      const k1 = Math.floor(s0 / step) + 1;
      const k2 = Math.floor((s0 + Math.min(speed * this.lookahead(), r.max_ahead_m)) / step);
      const ux = Math.cos(direction), uy = -Math.sin(direction);  // y up -> y down
      for (let k = k1; k <= k2; k++) {
        const d = k * step - s0;
        h.push(this._height(x0 + ux * d, y0 + uy * d));
        times.push(t0 + d / speed);
      }
    }
    // Bumps within runs on the picture (a run off it is never searched).
    const idx = [], prom = [];
    for (let i = 0; i < h.length;) {
      let e = i + 1;
      const on = !Number.isNaN(h[i]);
      while (e < h.length && !Number.isNaN(h[e]) === on) e++;
      if (on && e - i >= 3) {
        const ri = [], rp = [];
        peaks(h, i, e, this.floor, ri, rp);
        for (let c = 0; c < ri.length; c++) { idx.push(ri[c] + i); prom.push(rp[c]); }
      }
      i = e;
    }
    if (!idx.length) return [];
    const late = previous === null ? now - r.late_s : now - Math.min(r.lookahead_s, Math.max(r.late_s, now - previous));
    const scale = pressure === null || pressure === undefined ? 1 : Math.min(1, Math.max(0, pressure) / r.reference_pressure);
    this.pend = this._place(idx, prom, times, this.k0 + a, late, now, scale);
    return this.pend.map((e) => ({ t: e.t, s: e.s, f: e.f }));
  }

  lookahead() { return this.r.lookahead_s; }

  /** The stroke's rule on a window's bumps (surface/_stroke_kernels.py's place_crossings). */
  _place(idx, prom, tc, k0, late, now, scale) {
    const r = this.r, step = this.step, floor = this.floor, ring = this.ring;
    let c = [];
    for (let i = 0; i < idx.length; i++) {
      const ti = tc[idx[i]];
      if (ti <= late) continue;
      const si = (k0 + idx[i]) * step;
      if (ring.some((f) => { const d = f.arc - si; return -this.same < d && d < this.same; })) continue;
      const span = Math.log(Math.max(r.full_prominence / floor, 1 + 1e-9));
      c.push({ t: ti > now ? ti : now, arc: si, s: Math.min(1, Math.max(0, Math.log(Math.max(prom[i], 1e-12) / floor) / span)) * scale });
    }
    const n = c.length;
    if (!n) return [];
    c = c.map((e, i) => [e, i]).sort((p, q) => p[0].t - q[0].t || p[1] - q[1]).map((p) => p[0]);  // stable
    const t = c.map((e) => e.t), s = c.map((e) => e.s);
    const prev = this.lastFired, hasPrev = !Number.isNaN(prev);
    const fast = new Array(n).fill(false);
    const off = hasPrev ? 1 : 0, m = n + off;
    if (m > 1) {
      let any = false;
      for (let i = 0; i < n; i++) {
        const j = off + i;
        let d;
        if (j === 0) d = t[1] - t[0];
        else if (j === m - 1) d = t[i] - (i > 0 ? t[i - 1] : prev);
        else d = (t[i + 1] - (i > 0 ? t[i - 1] : prev)) / 2;
        fast[i] = d <= 0 || 1 / Math.max(d, 1e-12) > r.rate_only_hz;
        any = any || fast[i];
      }
      if (any) {
        // In place, as Python's rule does: a median already taken counts in the next.
        for (let i = 0; i < n; i++) {
          if (!fast[i]) continue;
          const v = s.slice(Math.max(0, i - 3), Math.min(n, i + 4)).sort((p, q) => p - q);
          s[i] = v.length % 2 ? v[(v.length - 1) / 2] : (v[v.length / 2 - 1] + v[v.length / 2]) / 2;
        }
      }
    }
    const out = [];
    let last = prev;
    for (let i = 0; i < n; i++) {
      const ti = t[i];
      let si = s[i], f = fast[i] ? RATE_ONLY : 0;
      if (hasPrev || out.length) {
        const gap = ti - last;
        if (gap < r.min_interval_s) {
          if (out.length) out[out.length - 1].f |= MERGED;
          continue;
        }
        if (gap < r.cluster_interval_s && !fast[i]) { si *= gap / r.cluster_interval_s; f |= CLUSTER; }
      }
      if (ti <= now) f |= LATE;
      out.push({ t: ti, s: si, f, arc: c[i].arc });
      last = ti;
    }
    return out;
  }
}

/** The tracker and the stroke together: what a page feeds each pointer batch. */
export class SurfaceRenderer {
  constructor(model, displayPitch) {
    this.model = model;
    this.tracker = new Tracker(model.header.rule.tracker);
    this.stroke = new SurfaceStroke(model, displayPitch);
  }

  /** A batch of samples [{t [s], x, y [display m], p}]: the events not yet fired [{t, s, f}]. */
  feed(batch) {
    for (const s of batch) this.tracker.add(s);
    const st = this.tracker.estimate;
    if (st === null) return [];
    return this.stroke.update(batch, st.speed, st.direction, st.pressure);
  }

  lift() { this.tracker.reset(); this.stroke.reset(); }
}

/** What an event-playing output fires for a whole stroke, cut into batches of batchS [s] each
 *  arriving transportS [s] after its newest sample (pen/replay.py's replay_stroke): [{t, s, f}]. */
export function replayStroke(model, displayPitch, samples, batchS = 0.004, transportS = 0.001) {
  const rd = new SurfaceRenderer(model, displayPitch);
  const fired = [];
  let schedule = [];
  const batches = [];
  for (const smp of samples) {
    if (batches.length && smp.t < batches[batches.length - 1][0].t + batchS) batches[batches.length - 1].push(smp);
    else batches.push([smp]);
  }
  for (const batch of batches) {
    const arrival = batch[batch.length - 1].t + transportS;
    for (const ev of schedule) if (ev.t + transportS <= arrival) fired.push({ ...ev, t: ev.t + transportS });
    for (const s of batch) rd.tracker.add(s);
    const st = rd.tracker.estimate;
    if (st === null) { schedule = []; continue; }
    schedule = rd.stroke.update(batch, st.speed, st.direction, st.pressure);
    schedule = schedule.filter((ev) => ev.t + transportS > arrival)
      .concat(schedule.filter((ev) => ev.t + transportS <= arrival).map((ev) => ({ ...ev, t: arrival - transportS })));
  }
  for (const ev of schedule) fired.push({ ...ev, t: ev.t + transportS });
  fired.sort((p, q) => p.t - q.t);
  return fired;
}

/** Each event as a wavelet row [dt_s, amplitude, sigma_s] from nowS (synthesis/wavelets.py's
 *  wavelet_rows): its width from the interval to the nearest neighbour, its peak inside the band. */
export function waveletRows(events, nowS, bandHz) {
  const k = Math.SQRT2 * Math.PI, lo = 1 / (k * bandHz[1]), hi = 1 / (k * bandHz[0]);
  return events.map((e, i) => {
    let gap = Infinity;
    if (i > 0 && e.t - events[i - 1].t > 0) gap = e.t - events[i - 1].t;
    if (i + 1 < events.length && events[i + 1].t - e.t > 0 && events[i + 1].t - e.t < gap) gap = events[i + 1].t - e.t;
    const sigma = gap !== Infinity ? gap / k : hi;
    return [e.t - nowS, e.s, Math.min(hi, Math.max(lo, sigma))];
  });
}
