// Audio output: the same drive updates feed an AudioWorklet pulse synthesiser.
// Off until the user turns it on (browsers only start audio after a gesture,
// and an actuator on an amplifier should never start by surprise).

/** Can this page play pulses?  The AudioWorklet exists only in a secure context
 *  (HTTPS, or loopback): over plain HTTP from a phone it does not. */
export function audioAvailable() {
  return typeof AudioContext === "function" && typeof AudioWorkletNode === "function" && window.isSecureContext !== false;
}

export class AudioPulses {
  constructor() { this.ctx = null; this.node = null; this.on = false; this.last = null; }

  async start() {
    if (!this.ctx) {
      this.ctx = new AudioContext({ latencyHint: "interactive" });
      await this.ctx.audioWorklet.addModule("/static/pulse-worklet.js");
      this.node = new AudioWorkletNode(this.ctx, "tactilize-pulse", { numberOfInputs: 0, outputChannelCount: [2] });
      this.node.connect(this.ctx.destination);
    }
    await this.ctx.resume();
    this.on = true;
    if (this.last) this.setDrives(this.last);
  }

  async stop() {
    this.on = false;
    if (this.node) this.node.port.postMessage({ channels: [{ f: 0 }, { f: 0 }] });
    if (this.ctx) await this.ctx.suspend();
  }

  /** Latency the browser reports [s]: the worklet's 128-frame quantum plus the rest. */
  latencyS() {
    if (!this.ctx) return null;
    return (this.ctx.baseLatency || 0) + (this.ctx.outputLatency || 0) + 128 / this.ctx.sampleRate;
  }

  setDrives(channels) {
    this.last = channels;
    if (!this.on || !this.node) return;
    this.node.port.postMessage({
      channels: channels.map((c) => ({ f: c.pulse_frequency_hz, w: c.pulse_width_s, a: c.amplitude })),
    });
  }
}
