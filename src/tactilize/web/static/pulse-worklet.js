// AudioWorklet pulse synthesiser: one rectangular pulse train per output channel
// (left = channel 1, right = channel 2), phase-continuous across drive changes,
// so a new frequency never produces a click or a skipped pulse.  It plays what the
// server's drives say, for a voice-coil or LRA actuator on the headphone jack.

class PulseProcessor extends AudioWorkletProcessor {
  constructor() {
    super();
    this.ch = [0, 1].map(() => ({ f: 0, w: 0, a: 0, gain: 0, phase: 0 }));
    this.port.onmessage = (e) => {
      const chans = e.data && e.data.channels;
      if (!Array.isArray(chans)) return;
      chans.slice(0, 2).forEach((c, i) => {
        const s = this.ch[i];
        s.f = c.f > 0 ? c.f : 0; s.w = c.w > 0 ? c.w : 0; s.a = c.a > 0 ? Math.min(1, c.a) : 0;
      });
    };
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
    return true;
  }
}

registerProcessor("tactilize-pulse", PulseProcessor);
