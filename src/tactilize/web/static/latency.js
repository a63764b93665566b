// The page's own latency figure: from a pen batch's newest sample (its own
// event timestamp) to the drive covering it arriving back here [ms], over the
// last second (docs/references.md, section 9 (simultaneity): felt as simultaneous
// under about 5 ms).

const WINDOW_MS = 1000;

export class LatencyMeter {
  constructor() {
    this.pending = [];  // [seq, newest sample's timeStamp [ms]] of batches awaiting their drive
    this.values = [];   // [arrival [ms], latency [ms]]
  }

  /** A batch went out: its seq and its newest sample's timestamp [ms]. */
  sent(seq, tMs) {
    this.pending.push([seq, tMs]);
    if (this.pending.length > 2000) this.pending.shift();
  }

  /** A drive came back covering every batch up to `seq`. */
  drive(seq, now = performance.now()) {
    while (this.pending.length && this.pending[0][0] <= seq) this.values.push([now, now - this.pending.shift()[1]]);
  }

  /** p50 and p99 [ms] over the last second, with how many batches; null when none. */
  stats(now = performance.now()) {
    while (this.values.length && this.values[0][0] < now - WINDOW_MS) this.values.shift();
    if (!this.values.length) return null;
    const v = this.values.map((x) => x[1]).sort((a, b) => a - b);
    const at = (p) => v[Math.min(v.length - 1, Math.floor(p * v.length))];
    return { n: v.length, p50: at(0.5), p99: at(0.99), max: v[v.length - 1] };
  }
}
