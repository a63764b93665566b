// AudioWorklet synthesiser for a voice-coil or LRA actuator on the headphone jack
// (left = channel 1, right = channel 2).  Two things play:
// - the steady rendering's pulse trains: one rectangular train per channel,
//   phase-continuous across drive changes, so a new frequency never clicks or skips;
// - the surface rendering's pulse events: each one the acceleration of the tip over
//   a bump, a wavelet -(1 - tau^2) exp(-tau^2 / 2), tau = (t - t_event) / sigma, cut at
//   3 sigma with a raised-cosine taper over the last sigma.  The server sets each
//   wavelet's amplitude and width (tactilize.synthesis.wavelets, docs/surfaces.md,
//   "Voice coils and the page's audio"); this only draws them.

// The rule's numbers are the server's (tactilize.synthesis.wavelets, served as the page's
// constants and handed over in processorOptions), set when the processor is made:
// SPAN the wavelet's half-width in sigmas (SPAN_SIGMAS); a new wavelet asked for within
// SAME_S [s] of one already kept is that one, re-sent; a kept wavelet re-sent with another
// strength glides to it over GLIDE_S [s]; a wavelet whose start has passed keeps its centre,
// its leading tail faded in over half of what is left, while LATE_SIGMAS remain before the crest.
let SPAN = 0, SAME_S = 0, GLIDE_S = 0, LATE_SIGMAS = 0;

function ricker(tau) {
  const a = Math.abs(tau);
  if (a >= SPAN) return 0;
  const w = -(1 - a * a) * Math.exp(-0.5 * a * a);
  return a <= SPAN - 1 ? w : w * (0.5 + 0.5 * Math.cos(Math.PI * (a - (SPAN - 1))));
}

class PulseProcessor extends AudioWorkletProcessor {
  constructor(options) {
    super();
    const rule = options.processorOptions.wavelet;
    SPAN = rule.span_sigmas; SAME_S = rule.same_s; GLIDE_S = rule.glide_s; LATE_SIGMAS = rule.late_sigmas;
    this.ch = [0, 1].map(() => ({ f: 0, w: 0, a: 0, gain: 0, phase: 0 }));
    this.wavelets = [];  // in frames, by start (see schedule)
    this.shares = [1, 1];  // each channel's share of a wavelet (the pen's two-channel split)
    this.played = 0;     // wavelets started so far (the page's tests count them)
    this.port.onmessage = (e) => {
      const d = e.data || {};
      const chans = d.channels;
      if (Array.isArray(chans)) {
        chans.slice(0, 2).forEach((c, i) => {
          const s = this.ch[i];
          s.f = c.f > 0 ? c.f : 0; s.w = c.w > 0 ? c.w : 0; s.a = c.a > 0 ? Math.min(1, c.a) : 0;
        });
      }
      if (Array.isArray(d.shares)) this.shares = d.shares.map((x) => (x >= 0 ? Math.min(1, x) : 1));
      if (Array.isArray(d.wavelets)) this.schedule(d.wavelets, +d.at || 0);
      if (d.clear) this.wavelets = [];
      if (Number.isFinite(d.until)) {
        // Keep what has started and what was asked for up to `until` (context time [s]).
        const last = d.until * sampleRate;
        this.wavelets = this.wavelets.filter((w) => w.start < currentFrame || w.want <= last);
      }
    };
  }

  /** Replace every wavelet not yet started and not yet due by rows [dt_s, amplitude,
   *  sigma_s], dt from `at` (the context's time of the message's newest pen sample), by the
   *  rules of tactilize.synthesis.wavelets.WaveletPlayer.replace: one kept is not scheduled
   *  again (its amplitude glides to the re-sent one); one whose start has passed keeps its
   *  centre with its leading tail faded in, or, too late for that, plays whole from now. */
  schedule(rows, at) {
    // `at` is where the message's newest pen sample falls: a wavelet asked for before it
    // belongs to an event that has fired on the stroke's clock, which the message no longer
    // carries; it stays, started or not.
    const now = currentFrame, fired = at * sampleRate;
    const kept = this.wavelets.filter((w) => w.start < now || w.want < fired);
    for (const r of rows) {
      const sigma = r[2] * sampleRate, amp = Math.max(0, Math.min(1, r[1]));
      if (!(sigma > 0) || !Number.isFinite(r[0])) continue;
      const want = (at + r[0]) * sampleRate;
      const match = kept.find((w) => Math.abs(w.want - want) < SAME_S * sampleRate);
      if (match) {
        if (match.amp !== amp) {
          if (match.start >= now) { match.amp = match.ampFrom = amp; }
          else {
            match.ampFrom = this.ampAt(match, now); match.amp = amp; match.g0 = now;
            match.g1 = Math.max(now + 1, Math.min(now + GLIDE_S * sampleRate, match.centre));
          }
        }
        continue;
      }
      let centre = want, start = centre - SPAN * sigma, fadeEnd = start;
      if (start < now) {
        if (centre - now >= LATE_SIGMAS * sigma) { start = now; fadeEnd = now + 0.5 * (centre - now); }
        else { centre = now + SPAN * sigma; start = now; fadeEnd = start; }
      }
      start = Math.floor(start);
      kept.push({ start, centre, want, amp, ampFrom: amp, g0: start, g1: start, fadeEnd, sigma, counted: false });
    }
    kept.sort((a, b) => a.start - b.start);
    this.wavelets = kept;
  }

  /** A wavelet's amplitude at frame f: its glide, then its fade-in. */
  ampAt(w, f) {
    let a = w.amp;
    if (w.amp !== w.ampFrom && f < w.g1) a = w.ampFrom + (w.amp - w.ampFrom) * Math.max(0, Math.min(1, (f - w.g0) / (w.g1 - w.g0)));
    if (f < w.fadeEnd) a *= 0.5 - 0.5 * Math.cos(Math.PI * Math.max(0, Math.min(1, (f - w.start) / (w.fadeEnd - w.start))));
    return a;
  }

  process(inputs, outputs) {
    const out = outputs[0];
    const n = out[0].length;
    // Amplitude glides over ~2 ms to avoid clicks; off is immediate (the pen lifted).
    const glide = 1 - Math.exp(-1 / (0.002 * sampleRate));
    for (let c = 0; c < out.length; c++) {
      const s = this.ch[Math.min(c, 1)];
      const buf = out[c];
      if (s.f <= 0 || s.w <= 0 || s.a <= 0) { s.gain = 0; buf.fill(0); continue; }
      const dp = s.f / sampleRate, duty = Math.min(1, s.w * s.f);
      for (let k = 0; k < n; k++) {
        s.gain += (s.a - s.gain) * glide;
        buf[k] = s.phase < duty ? s.gain : 0;
        s.phase += dp;
        if (s.phase >= 1) s.phase -= Math.floor(s.phase);
      }
    }
    if (this.wavelets.length) {
      const f0 = currentFrame, f1 = f0 + n;
      const live = [];
      for (const w of this.wavelets) {
        const end = w.centre + SPAN * w.sigma;
        if (w.start < f1) {
          if (!w.counted) { w.counted = true; this.played++; this.port.postMessage({ played: this.played, t: w.want / sampleRate }); }
          const a = Math.max(w.start, f0), b = Math.min(Math.ceil(end) + 1, f1);
          for (let f = a; f < b; f++) {
            const v = this.ampAt(w, f) * ricker((f - w.centre) / w.sigma);
            for (let c = 0; c < out.length; c++) out[c][f - f0] += v * this.shares[Math.min(c, 1)];
          }
        }
        if (end >= f1) live.push(w);
      }
      this.wavelets = live;
    }
    return true;
  }
}

registerProcessor("tactilize-pulse", PulseProcessor);
