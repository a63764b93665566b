// The surface rendering's rule in the browser: a pulse event per bump the pen crosses.
//
// The JavaScript copy of what tactilize.surface and tactilize.pen run in Python
// (docs/surfaces.md, "What is rendered" and "Along the stroke, in real time"):
// the tracker's least-squares velocity (pen/tracker.py), the path on a grid fixed
// in arc length and its window from 4 mm behind the pen to the look-ahead
// (surface/path.py), the heights by bilinear lookup and the bumps by prominence
// (surface/_kernels.py), and the stroke's bookkeeping: too late, already played,
// strengths, clusters, rate only (surface/_stroke_kernels.py, surface/stroke.py).
// A material's micro-roughness is drawn where the pen is as materials/roughness.py draws it
// (MicroRoughness.height_m: the same hashed lattice of Gaussian bumps, the same numbers).
// Every parameter comes from the model file, written by Python
// (tactilize.site.model_file), so the two cannot drift apart silently;
// tests/test_site_browser.py runs both on the same strokes in headless Chromium.
// Arithmetic follows the Python order step by step, so heights and times agree
// to rounding, not just to a tolerance.
//
// Units: SI (s, m), as in Python; positions in display metres, y down.

const MAGIC = 0x31465354; // "TSF1" read as a little-endian uint32

// Inflate (RFC 1950 / 1951), synchronous.  The browser's DecompressionStream does the same
// natively but only through a stream, several tasks apart; on a slow phone's busy main
// thread, while the page is still loading, each of those tasks waits its turn, and the
// model was ready up to a few hundred ms after the page.  This decodes the heights (about
// 60 KB) in one go, in a few ms.
const LEN_BASE = [3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 15, 17, 19, 23, 27, 31, 35, 43, 51, 59, 67, 83, 99, 115,
  131, 163, 195, 227, 258];
const LEN_EXTRA = [0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0];
const DIST_BASE = [1, 2, 3, 4, 5, 7, 9, 13, 17, 25, 33, 49, 65, 97, 129, 193, 257, 385, 513, 769, 1025, 1537,
  2049, 3073, 4097, 6145, 8193, 12289, 16385, 24577];
const DIST_EXTRA = [0, 0, 0, 0, 1, 1, 2, 2, 3, 3, 4, 4, 5, 5, 6, 6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13, 13];
const CODE_LENGTH_ORDER = [16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15];

/** A canonical Huffman code as a table indexed by the next `bits` input bits (least
 *  significant first, as deflate packs them): entry = symbol << 4 | code length, 0 = no code. */
function huffmanTable(lengths) {
  let bits = 0;
  const count = new Uint16Array(16);
  for (const l of lengths) { count[l]++; if (l > bits) bits = l; }
  count[0] = 0;
  const next = new Uint16Array(16);
  for (let b = 1, code = 0; b < 16; b++) { code = (code + count[b - 1]) << 1; next[b] = code; }
  const table = new Uint32Array(1 << bits);
  for (let sym = 0; sym < lengths.length; sym++) {
    const len = lengths[sym];
    if (!len) continue;
    // Codes are sent first bit first, so the table is indexed by the code bit-reversed.
    let c = next[len]++, rev = 0;
    for (let k = 0; k < len; k++) { rev = (rev << 1) | (c & 1); c >>= 1; }
    for (let i = rev; i < table.length; i += 1 << len) table[i] = (sym << 4) | len;
  }
  return { table, bits };
}

let fixedCodes = null;
function fixedHuffman() {
  if (!fixedCodes) {
    const lit = new Uint8Array(288).fill(8, 0, 144).fill(9, 144, 256).fill(7, 256, 280).fill(8, 280, 288);
    fixedCodes = [huffmanTable(lit), huffmanTable(new Uint8Array(30).fill(5))];
  }
  return fixedCodes;
}

/** The bytes of a zlib stream, which must be exactly `size` long (Uint8Array). */
export function inflate(src, size) {
  const bad = (why) => { throw new Error(`damaged surface model (${why})`); };
  if (src.length < 6 || (src[0] & 0x0f) !== 8 || ((src[0] << 8) | src[1]) % 31 !== 0 || (src[1] & 0x20)) bad("zlib header");
  const out = new Uint8Array(size);
  let pos = 2, buf = 0, cnt = 0, o = 0;
  // The bit reader: up to 24 bits at a time; past the end it reads zeros, caught below.
  const need = (n) => { while (cnt < n) { buf |= (pos < src.length ? src[pos] : 0) << cnt; pos++; cnt += 8; } };
  const take = (n) => { need(n); const v = buf & ((1 << n) - 1); buf >>>= n; cnt -= n; return v; };
  const symbol = (code) => {
    need(code.bits);
    const e = code.table[buf & ((1 << code.bits) - 1)];
    if (!(e & 15)) bad("code");
    buf >>>= e & 15; cnt -= e & 15;
    return e >>> 4;
  };
  let last = 0;
  while (!last) {
    last = take(1);
    const type = take(2);
    if (type === 0) {
      // Stored: from the next byte boundary, LEN and its complement, then LEN bytes.
      pos -= cnt >> 3; buf = 0; cnt = 0;
      const len = src[pos] | (src[pos + 1] << 8), nlen = src[pos + 2] | (src[pos + 3] << 8);
      if ((len ^ 0xffff) !== nlen || pos + 4 + len > src.length || o + len > size) bad("stored block");
      out.set(src.subarray(pos + 4, pos + 4 + len), o);
      pos += 4 + len; o += len;
      continue;
    }
    let lit, dist;
    if (type === 1) [lit, dist] = fixedHuffman();
    else if (type === 2) {
      const nlit = take(5) + 257, ndist = take(5) + 1, nclen = take(4) + 4;
      const clen = new Uint8Array(19);
      for (let i = 0; i < nclen; i++) clen[CODE_LENGTH_ORDER[i]] = take(3);
      const cl = huffmanTable(clen);
      const lengths = new Uint8Array(nlit + ndist);
      for (let i = 0; i < lengths.length;) {
        const sym = symbol(cl);
        if (sym < 16) { lengths[i++] = sym; continue; }
        let rep, val = 0;
        if (sym === 16) { if (!i) bad("repeat"); val = lengths[i - 1]; rep = 3 + take(2); }
        else rep = sym === 17 ? 3 + take(3) : 11 + take(7);
        if (i + rep > lengths.length) bad("repeat");
        lengths.fill(val, i, i + rep); i += rep;
      }
      lit = huffmanTable(lengths.subarray(0, nlit));
      dist = huffmanTable(lengths.subarray(nlit));
    } else bad("block type");
    for (;;) {
      const sym = symbol(lit);
      if (sym < 256) { if (o >= size) bad("too long"); out[o++] = sym; continue; }
      if (sym === 256) break;
      const li = sym - 257;
      if (li >= 29) bad("length");
      const len = LEN_BASE[li] + take(LEN_EXTRA[li]);
      const di = symbol(dist);
      if (di >= 30) bad("distance");
      const d = DIST_BASE[di] + take(DIST_EXTRA[di]);
      if (d > o || o + len > size) bad("match");
      for (let k = 0; k < len; k++, o++) out[o] = out[o - d];
    }
    if (pos - (cnt >> 3) > src.length) bad("truncated");
  }
  if (o !== size) bad(`${o} heights, not ${size}`);
  return out;
}

/** Decode a model file (an ArrayBuffer), synchronously: {header, cols, rows, levels (Uint8Array,
 *  padded by one edge pixel all round, as SurfaceModel.lookup_table), heightOf (Float32Array(256))}. */
export function decodeModel(buffer) {
  const view = new DataView(buffer);
  if (buffer.byteLength < 8 || view.getUint32(0, true) !== MAGIC) throw new Error("not a tactilize surface model");
  const n = view.getUint32(4, true);
  const header = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 8, n)));
  const { cols, rows } = header;
  const r = inflate(new Uint8Array(buffer, 8 + n), cols * rows);
  // Undo the predictor straight into the padded grid, a byte per pixel and no branch inside
  // a row: the least work per pixel while the page loads.  The heights are looked up per
  // level when read: offset + q * scale in float64, stored as float32, as Python's
  // ModelFile.heights computes them.
  const pc = cols + 2, q = new Uint8Array(pc * (rows + 2));
  const grad = header.predictor === "gradient";
  for (let y = 0; y < rows; y++) {
    const o = y * cols, f = (y + 1) * pc + 1;
    let v = 0, x = 0;
    if (grad && y > 0) {
      v = q[f] = (q[f - pc] + r[o]) & 0xff;
      for (x = 1; x < cols; x++) v = q[f + x] = (v + q[f - pc + x] - q[f - pc + x - 1] + r[o + x]) & 0xff;
    } else {
      for (; x < cols; x++) v = q[f + x] = (v + r[o + x]) & 0xff;
    }
    q[f - 1] = q[f];
    q[f + cols] = v;
  }
  q.copyWithin(0, pc, 2 * pc);
  q.copyWithin((rows + 1) * pc, rows * pc, (rows + 1) * pc);
  const heightOf = new Float32Array(256);
  for (let k = 0; k < 256; k++) heightOf[k] = header.offset + k * header.scale;
  return { header, cols, rows, levels: q, heightOf };
}

/** decodeModel, for callers holding a promise of the bytes. */
export async function parseModel(buffer) { return decodeModel(buffer); }

const MASK64 = (1n << 64n) - 1n;
const NODE_CACHE = 128;  // nodes per side of the table of normal numbers (a power of two)
const M1 = 0xBF58476D1CE4E5B9n, M2 = 0x94D049BB133111EBn, NODE_U = 0x9E3779B1n, NODE_V = 0x85EBCA77n;

/** The splitmix64 finaliser on a 64-bit word (BigInt), wrapping modulo 2^64 as numpy's uint64 does. */
function mix(z) {
  z = ((z ^ (z >> 30n)) * M1) & MASK64;
  z = ((z ^ (z >> 27n)) * M2) & MASK64;
  return z ^ (z >> 31n);
}

/** A material's micro-roughness as the tip follows it (materials/roughness.py's MicroRoughness),
 *  from the model header's `micro`: heights [m] at points of the real surface [m]. */
export class MicroRoughness {
  constructor(p) {
    this.spacing = p.spacing_m;
    this.weight = p.node_weight_m;
    this.reach = p.reach;
    const r = p.spacing_m / p.sigma_m;
    this.k = -0.5 * (r * r);
    this.seed = BigInt("0x" + p.seed_word);
    // A node's normal number, kept in a direct-mapped table by its low bits: a stroke meets each
    // node for many points in a row, and hashing in BigInt is the slow part.
    this.tagU = new Int32Array(NODE_CACHE * NODE_CACHE).fill(-0x80000000);
    this.tagV = new Int32Array(NODE_CACHE * NODE_CACHE);
    this.value = new Float64Array(NODE_CACHE * NODE_CACHE);
    this.gv = new Float64Array(2 * p.reach + 1);
  }

  /** The standard normal number of lattice node (iu, iv) (Box-Muller on its hash's two halves). */
  normal(iu, iv) {
    const slot = ((iu & (NODE_CACHE - 1)) * NODE_CACHE) | (iv & (NODE_CACHE - 1));
    if (this.tagU[slot] === iu && this.tagV[slot] === iv) return this.value[slot];
    const h = mix((BigInt.asUintN(64, BigInt(iu)) * NODE_U & MASK64) ^ (BigInt.asUintN(64, BigInt(iv)) * NODE_V & MASK64) ^ this.seed);
    const lo = (Number(h & 0xFFFFFFFFn) + 0.5) / 4294967296.0, hi = (Number(h >> 32n) + 0.5) / 4294967296.0;
    const n = Math.sqrt(-2.0 * Math.log(lo)) * Math.cos(2.0 * Math.PI * hi);
    this.tagU[slot] = iu; this.tagV[slot] = iv; this.value[slot] = n;
    return n;
  }

  /** Height [m] at (x, y) [m on the real surface]: the nodes within `reach` either side, in Python's order. */
  height(x, y) {
    const u = x / this.spacing, v = y / this.spacing;
    const iu = Math.floor(u), iv = Math.floor(v), fu = u - iu, fv = v - iv, R = this.reach, k = this.k;
    const gv = this.gv;  // the row factors, the same for every du
    for (let dv = -R; dv <= R; dv++) gv[dv + R] = Math.exp(k * ((fv - dv) * (fv - dv)));
    const tagU = this.tagU, tagV = this.tagV, value = this.value, M = NODE_CACHE - 1;
    let out = 0;
    for (let du = -R; du <= R; du++) {
      const gu = Math.exp(k * ((fu - du) * (fu - du))), nu = iu + du, row = (nu & M) * NODE_CACHE;
      for (let dv = -R; dv <= R; dv++) {
        const nv = iv + dv, slot = row | (nv & M);
        const n = tagU[slot] === nu && tagV[slot] === nv ? value[slot] : this.normal(nu, nv);
        out += n * gu * gv[dv + R];
      }
    }
    return out * this.weight;
  }
}

/** Map coordinates' bilinear lookup (order 1, mode "nearest") at row cy, column cx of the padded
 *  levels q, each level's height h[level]. */
function bilinear(q, h, R, C, cy, cx) {
  cy = cy < 0 ? 0 : (cy > R - 1 ? R - 1 : cy);
  cx = cx < 0 ? 0 : (cx > C - 1 ? C - 1 : cx);
  const fy = Math.floor(cy), fx = Math.floor(cx);
  const r0 = fy, c0 = fx;
  const wy0 = 1 - (cy - fy), wy1 = 1 - wy0, wx0 = 1 - (cx - fx), wx1 = 1 - wx0;
  const r1 = r0 + 1 < R ? r0 + 1 : Math.max(R - 2, 0);
  const c1 = c0 + 1 < C ? c0 + 1 : Math.max(C - 2, 0);
  let t = 0;
  t += (h[q[r0 * C + c0]] * wy0) * wx0;
  t += (h[q[r0 * C + c1]] * wy0) * wx1;
  t += (h[q[r1 * C + c0]] * wy1) * wx0;
  t += (h[q[r1 * C + c1]] * wy1) * wx1;
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
    this.full = h.full_prominence;
    // The micro-roughness is drawn on the real surface: display metres times real per display.
    this.micro = h.micro ? new MicroRoughness(h.micro) : null;
    this.real = [h.surface_pitch_m[0] / displayPitch[0], h.surface_pitch_m[1] / displayPitch[1]];
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
    if (!(px >= 0 && px < m.cols && py >= 0 && py < m.rows)) return NaN;
    const h = bilinear(m.levels, m.heightOf, m.rows + 2, m.cols + 2, py + 0.5, px + 0.5);
    return this.micro === null ? h : h + this.micro.height(x * this.real[0], y * this.real[1]);
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
      // Read history_m beyond the look-ahead (a bump handed out has as much profile ahead as behind).
      const k2 = Math.floor((s0 + Math.min(speed * this.lookahead() + r.history_m, r.max_ahead_m)) / step);
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
    const horizon = now + r.lookahead_s;
    for (let i = 0; i < idx.length; i++) {
      const ti = tc[idx[i]];
      if (ti <= late || ti > horizon) continue;
      const si = (k0 + idx[i]) * step;
      // A fired pulse's arcs: its bump's and those of the crossings merged into it.
      if (ring.some((f) => f.arc - this.same < si && si < f.lastArc + this.same)) continue;
      const span = Math.log(Math.max(this.full / floor, 1 + 1e-9));
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
          // Merged into the pulse before (this batch's, or the last fired): its arc is that pulse's.
          if (out.length) { out[out.length - 1].f |= MERGED; out[out.length - 1].lastArc = c[i].arc; }
          else if (ring.length) ring[ring.length - 1].lastArc = Math.max(ring[ring.length - 1].lastArc, c[i].arc);
          continue;
        }
        if (gap < r.cluster_interval_s && !fast[i]) { si *= gap / r.cluster_interval_s; f |= CLUSTER; }
      }
      if (ti <= now) f |= LATE;
      out.push({ t: ti, s: si, f, arc: c[i].arc, lastArc: c[i].arc });
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

/** What an event-playing output fires for a whole stroke, cut into batches of batchS [s] on a grid
 *  from the first sample, each arriving transportS [s] after its newest sample (surface/playback.py's
 *  play_stroke): [{t, s, f}], t on the stroke's clock. */
export function replayStroke(model, displayPitch, samples, batchS = 0.004, transportS = 0.001) {
  const rd = new SurfaceRenderer(model, displayPitch);
  const fired = [];
  let schedule = [];
  const batches = [];
  if (samples.length) {
    const t0 = samples[0].t;
    const slot = (t) => Math.floor((t - t0) / batchS + 1e-6);  // a sample on a boundary opens the next
    for (const smp of samples) {
      const b = batches[batches.length - 1];
      if (b && slot(b[0].t) === slot(smp.t)) b.push(smp);
      else batches.push([smp]);
    }
  }
  let now = -Infinity;
  for (const batch of batches) {
    now = batch[batch.length - 1].t;
    // Due by the time this batch arrives (the output's clock, transportS behind the host's): fired.
    for (const ev of schedule) if (ev.t <= now) fired.push(ev);
    for (const s of batch) rd.tracker.add(s);
    const st = rd.tracker.estimate;
    if (st === null) { schedule = []; rd.stroke.reset(); continue; }
    schedule = rd.stroke.update(batch, st.speed, st.direction, st.pressure);
  }
  for (const ev of schedule) if (ev.t <= now) fired.push(ev);
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
