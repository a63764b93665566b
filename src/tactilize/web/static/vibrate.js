// The phone's own vibration motor as an output: the rendering's pulses as
// navigator.vibrate() patterns.
//
// The Vibration API can only switch the motor on and off for whole milliseconds
// (docs/references.md, section 5 (Vibration API)): no amplitude, no frequency.
// A phone's motor takes about 10 .. 20 ms to respond: docs/references.md, section 5 (phone motors).
// So each pulse becomes one on-time of 10 .. 20 ms, longer for a stronger pulse,
// and pulses closer than 1/MAX_RATE_HZ are thinned out: the motor cannot follow
// faster ones (the paper's 100 .. 300 Hz pulse trains are far out of its reach;
// what a phone renders is the slow rhythm of a slow stroke, bump by bump).
//
// Pulses come from a *source*: a function (fromMs, toMs) -> [{t_ms, strength}] in
// page time (performance.now()).  The steady drive the page receives is one source
// (pulsesFromDrive); a list of pulse events rendered elsewhere is another
// (playPulses).  Every VIBRATE_EVERY_MS the player asks the source for the next
// WINDOW_MS and hands the browser one pattern that starts on a pulse; a new call
// replaces the rest of the last pattern, so the rhythm carries on unbroken.

/** At most this many pulses a second [Hz]. */
export const MAX_RATE_HZ = 25;
/** On-time of the weakest and the strongest pulse [ms]: what the motor needs to respond. */
export const MIN_ON_MS = 10;
export const MAX_ON_MS = 20;
/** Each pattern covers this much of what comes [ms]; a new one follows after VIBRATE_EVERY_MS. */
export const WINDOW_MS = 300;
export const VIBRATE_EVERY_MS = 100;

/** Is there a motor to drive?  The API, on a device with a touch screen. */
export function vibrationAvailable() {
  return typeof navigator !== "undefined" && typeof navigator.vibrate === "function"
    && typeof matchMedia === "function" && matchMedia("(any-pointer: coarse)").matches;
}

const clamp01 = (x) => (Number.isFinite(x) ? Math.min(1, Math.max(0, x)) : 1);

/** The pulses of a steady drive channel in [fromMs, toMs): one every 1/f, the first
 *  one period after `lastMs` (the last pulse played), or at fromMs after a pause. */
export function pulsesFromDrive(channel, fromMs, toMs, lastMs = -Infinity) {
  const f = channel ? channel.pulse_frequency_hz : 0;
  if (!(f > 0)) return [];
  const period = 1000 / f;
  const strength = clamp01(Number.isFinite(channel.strength) ? channel.strength : channel.amplitude);
  if (strength <= 0) return [];
  // A timer may fire up to a millisecond early or late: a pulse due then is not a pause.
  let t = lastMs + period >= fromMs - 1 ? lastMs + period : fromMs;
  const out = [];
  for (; t < toMs; t += period) out.push({ t_ms: t, strength });
  return out;
}

/** A navigator.vibrate() pattern for pulses: [on, off, on, ...] in whole ms >= 1.
 *
 *  Returns {startMs, pattern, pulses}: the pattern starts at startMs (the first
 *  pulse kept) and `pulses` are those kept: none closer than 1000/maxRateHz ms to
 *  the one before, none without strength.  A pulse's on-time grows with its
 *  strength from MIN_ON_MS to MAX_ON_MS and always leaves 1 ms off before the next. */
export function patternFor(pulses, { maxRateHz = MAX_RATE_HZ, minOnMs = MIN_ON_MS, maxOnMs = MAX_ON_MS } = {}) {
  const gap = 1000 / maxRateHz;
  const kept = [];
  for (const p of [...pulses].sort((a, b) => a.t_ms - b.t_ms)) {
    if (!(p.strength > 0)) continue;
    if (kept.length && p.t_ms - kept[kept.length - 1].t_ms < gap - 1e-9) continue;
    kept.push(p);
  }
  if (!kept.length) return { startMs: null, pattern: [], pulses: [] };
  const at = kept.map((p) => Math.round(p.t_ms));
  const pattern = [];
  for (let i = 0; i < kept.length; i++) {
    let on = Math.max(1, Math.round(minOnMs + (maxOnMs - minOnMs) * clamp01(kept[i].strength)));
    if (i + 1 < kept.length) {
      const span = at[i + 1] - at[i];
      on = Math.max(1, Math.min(on, span - 1));
      pattern.push(on, Math.max(1, span - on));
    } else {
      pattern.push(on);
    }
  }
  return { startMs: at[0], pattern, pulses: kept };
}

/** A new pattern may start this much before its first pulse is due [ms]: a timer
 *  firing late would otherwise find that pulse already started by the old pattern. */
export const EARLY_MS = 3;

/** Plays a pulse source on the motor.  `nav`, `now` and the timers are the page's
 *  unless given (tests give their own).
 *
 *  A call to vibrate() replaces the pattern playing and starts its own first pulse
 *  at once, so a new pattern is handed over only in an off-gap, at its first pulse
 *  (up to EARLY_MS early) and never sooner than 1/MAX_RATE_HZ after the pulse the
 *  old one last started: no pulse is doubled, cut or crowded at a handover. */
export class VibrationPulses {
  constructor({ nav = typeof navigator !== "undefined" ? navigator : null, now = () => performance.now(),
    setTimer = (f, ms) => setTimeout(f, ms), clearTimer = (id) => clearTimeout(id) } = {}) {
    Object.assign(this, { nav, now, setTimer, clearTimer });
    this.on = false;
    this.source = null;     // (fromMs, toMs) -> pulses, or null: still
    this.drive = null;      // the steady drive channel behind the source, if that is the source
    this.current = null;    // the pattern playing: {starts, ons, seen} [ms, page time]
    this.lastPulseMs = -Infinity;  // the last pulse the motor started
    this.lastOnEndMs = -Infinity;  // ... and when it ended
    this.timer = 0;
    this.played = [];       // [{t_ms, on_ms}] the pulses the motor started (last 2,000)
  }

  /** Turn on; call from the tap that asks for it (browsers want a user gesture). */
  start() { this.on = true; if (this.source) this._tick(false); }

  stop() { this._still(); this.on = false; }

  /** Follow the page's steady drive: the first channel that pulses. */
  setDrives(channels) {
    const c = (channels || []).find((ch) => ch && ch.pulse_frequency_hz > 0 && clamp01(ch.strength ?? ch.amplitude) > 0) || null;
    if (!c) { this.drive = null; this._still(); return; }
    const was = this.drive;
    this.drive = c;
    this.source = (from, to) => pulsesFromDrive(this.drive, from, to, this.lastPulseMs);
    // A new rhythm is handed over at once; a small change waits for the next refresh.
    const moved = !was || Math.abs(c.pulse_frequency_hz - was.pulse_frequency_hz) > 0.05 * was.pulse_frequency_hz
      || Math.abs(clamp01(c.strength ?? c.amplitude) - clamp01(was.strength ?? was.amplitude)) > 0.1;
    if (this.on && (moved || !this.timer)) this._tick(moved);
  }

  /** Play rendered pulse events [{t_ms, strength}] (page time) instead of the steady drive. */
  playPulses(pulses) {
    const list = [...pulses].sort((a, b) => a.t_ms - b.t_ms);
    this.drive = null;
    this.source = (from, to) => list.filter((p) => p.t_ms >= from - 1 && p.t_ms < to && p.t_ms > this.lastPulseMs);
    if (this.on) this._tick(true);
  }

  /** Note the pulses of the current pattern that have started by `now`. */
  _sync(now) {
    const cur = this.current;
    if (!cur) return;
    while (cur.seen < cur.starts.length && cur.starts[cur.seen] <= now) {
      const t = cur.starts[cur.seen], on = cur.ons[cur.seen];
      this.lastPulseMs = t; this.lastOnEndMs = t + on;
      this.played.push({ t_ms: t, on_ms: on });
      cur.seen++;
    }
    if (this.played.length > 2000) this.played.splice(0, this.played.length - 2000);
  }

  _later(ms, moved = false) {
    if (this.timer) this.clearTimer(this.timer);
    this.timer = this.setTimer(() => { this.timer = 0; this._tick(moved); }, Math.max(1, ms));
  }

  _still() {
    if (this.timer) { this.clearTimer(this.timer); this.timer = 0; }
    this.source = null;
    const now = this.now();
    this._sync(now);
    const cur = this.current;
    // Stop what is still to play (the on-pulse under way too: the pen is still).
    if (cur && this.nav && (cur.seen < cur.starts.length || this.lastOnEndMs > now)) this.nav.vibrate(0);
    this.current = null;
  }

  _tick(moved) {
    if (this.timer) { this.clearTimer(this.timer); this.timer = 0; }
    if (!this.on || !this.source) return;
    const now = this.now();
    this._sync(now);
    // The rate limit holds across patterns too: nothing sooner than 1/MAX_RATE_HZ after the last pulse.
    const soonest = this.lastPulseMs + 1000 / MAX_RATE_HZ - 1e-9;
    const { startMs, pattern } = patternFor(this.source(now, now + WINDOW_MS).filter((q) => q.t_ms >= soonest));
    const cur = this.current;
    const oldNext = cur && cur.seen < cur.starts.length ? cur.starts[cur.seen] : null;
    if (!pattern.length) {  // nothing to play yet: let the old pattern run out, look again later
      this._later(VIBRATE_EVERY_MS);
      return;
    }
    const due = Math.max(startMs - EARLY_MS, soonest, this.lastOnEndMs);
    if (due > now) {
      // A new rhythm: the old pattern's pulses before it are stopped (between pulses, never in one).
      if (moved && oldNext !== null && oldNext < startMs && now >= this.lastOnEndMs) {
        this.nav.vibrate(0);
        this.current = null;
      }
      this._later(due - now, moved);
      return;
    }
    // The clock again, just before the call: on a busy page the work above can take
    // long enough for the old pattern to start its next pulse meanwhile.  Then hand
    // over after that pulse instead of playing a second one on top of it.
    const c = this.now();
    if (oldNext !== null && c >= oldNext - 0.5) {
      this._later(oldNext + 1 - c);
      return;
    }
    this.nav.vibrate(pattern);
    const starts = [], ons = [];
    for (let i = 0, t = c; i < pattern.length; i += 2) {
      starts.push(t); ons.push(pattern[i]);
      t += pattern[i] + (pattern[i + 1] || 0);
    }
    this.current = { starts, ons, seen: 0 };
    this._sync(c);
    // The next pattern takes over at the pulse about VIBRATE_EVERY_MS on, or when this one ends.
    const k = starts.findIndex((t) => t - c >= VIBRATE_EVERY_MS);
    const end = starts[starts.length - 1] + ons[ons.length - 1];
    this._later((k > 0 ? starts[k] - EARLY_MS : end) - c);
  }
}
