// Audio output: the same drive updates feed an AudioWorklet synthesiser.  The steady
// rendering plays pulse trains; the surface rendering plays each pulse event as the
// acceleration wavelet the server sends with it (docs/surfaces.md, "Voice coils and
// the page's audio").  Off until the user turns it on (browsers only start audio
// after a gesture, and an actuator on an amplifier should never start by surprise).

import { constants } from "./constants.js";

/** Can this page play pulses?  The AudioWorklet exists only in a secure context
 *  (HTTPS, or loopback): over plain HTTP from a phone it does not. */
export function audioAvailable() {
  return typeof AudioContext === "function" && typeof AudioWorkletNode === "function" && window.isSecureContext !== false;
}

// Wavelets play this long after the message that scheduled them would place them [s]:
// one render quantum and a little more, so a message a few ms late moves nothing.
const LEAD_S = 0.010;

export class AudioPulses {
  constructor() { this.ctx = null; this.node = null; this.on = false; this.last = null; this.played = 0; this.playedAt = []; this.offset = null; this.lastAt = 0; }

  async start() {
    if (!this.ctx) {
      this.ctx = new AudioContext({ latencyHint: "interactive" });
      await this.ctx.audioWorklet.addModule("/static/pulse-worklet.js");
      // The wavelet rule's numbers are the server's (tactilize.synthesis.wavelets): the worklet has no fetch.
      this.node = new AudioWorkletNode(this.ctx, "tactilize-pulse", { numberOfInputs: 0, outputChannelCount: [2],
                                                                      processorOptions: { wavelet: constants.wavelet } });
      this.node.port.onmessage = (e) => {
        // Wavelets started, and when each was asked for (context time [s]): the tests read them.
        if (!e.data || !e.data.played) return;
        this.played = e.data.played;
        this.playedAt.push(e.data.t);
        if (this.playedAt.length > 1000) this.playedAt.splice(0, this.playedAt.length - 1000);
      };
      this.node.connect(this.ctx.destination);
    }
    await this.ctx.resume();
    this.on = true;
    if (this.last) this.setDrives(this.last);
  }

  async stop() {
    this.on = false;
    if (this.node) this.node.port.postMessage({ channels: [{ f: 0 }, { f: 0 }], clear: true });
    if (this.ctx) await this.ctx.suspend();
  }

  /** Latency the browser reports [s]: the worklet's 128-frame quantum plus the rest. */
  latencyS() {
    if (!this.ctx) return null;
    return (this.ctx.baseLatency || 0) + (this.ctx.outputLatency || 0) + 128 / this.ctx.sampleRate;
  }

  /** One drive message's channels (and, for the surface rendering, its wavelets).  Called
   *  without a message (a readout refresh, the pen lifted on the page) it changes nothing of
   *  a surface's wavelets but silence. */
  setDrives(channels, msg) {
    this.last = channels;
    if (msg) this.surface = msg.rendering === "surface";
    if (!this.on || !this.node) return;
    const silent = channels.every((c) => !(c.pulse_frequency_hz > 0));
    if (this.surface && !silent) {
      if (!msg) return;
      // The stroke's clock on the context's, fixed for the stroke with a lead of LEAD_S:
      // a message arriving late shifts nothing, and an event re-sent lands where it was.
      if (this.offset === null || !Number.isFinite(msg.t_s)) this.offset = this.ctx.currentTime + LEAD_S - (msg.t_s || 0);
      // Events, not a steady train: these wavelets replace those not yet started.
      this.lastAt = this.offset + (msg.t_s || 0);
      // Each channel's share as in the drive (the pen's two-channel split by direction).
      const amps = channels.map((c) => (c.amplitude > 0 ? c.amplitude : 0));
      const loudest = Math.max(...amps, 0);
      this.node.port.postMessage({
        channels: [{ f: 0 }, { f: 0 }],
        wavelets: Array.isArray(msg.wavelets) ? msg.wavelets : [],
        shares: amps.map((a) => (loudest > 0 ? a / loudest : 1)),
        at: this.lastAt,
      });
      return;
    }
    if (this.surface && silent && this.offset !== null) {
      // The pen lifted or stopped: the bumps it crossed up to its last sample still play
      // (the audio may run a little late), those ahead of it never will.
      this.node.port.postMessage({ channels: [{ f: 0 }, { f: 0 }], until: this.lastAt });
      this.offset = null;
      return;
    }
    this.offset = null;
    this.node.port.postMessage({
      channels: channels.map((c) => ({ f: c.pulse_frequency_hz, w: c.pulse_width_s, a: c.amplitude })),
      clear: true,
    });
  }
}
