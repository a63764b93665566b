// Where the plot and the trail are drawn.  In a worker on OffscreenCanvases where
// the browser can (draw-worker.js): canvas drawing is the page's largest main-thread
// cost, and a drive arriving while the main thread draws waits for it (a headless,
// software-rendered Chromium measured a median 5.4 ms of main-thread work per frame
// with the drawing on it).  Elsewhere, the same classes draw in the page.
// Both give the same calls; `mode` says which one runs ("worker" or "page").

import { Plot } from "./plot.js";
import { Trail } from "./trail.js";

export function startDrawing(plotCanvas, trailCanvas, channels = 2, onError = () => {}) {
  if (moduleWorkers() && typeof plotCanvas.transferControlToOffscreen === "function") {
    try {
      const worker = new Worker(new URL("./draw-worker.js", import.meta.url), { type: "module" });
      const plot = plotCanvas.transferControlToOffscreen();
      const trail = trailCanvas.transferControlToOffscreen();
      // The canvases are the worker's now: a failure there can only be reported.
      worker.onerror = (ev) => onError(`drawing worker: ${ev.message || "failed to start"}`);
      worker.postMessage({ type: "init", plot, trail, channels }, [plot, trail]);
      // Samples and drives come once per pen event (250 a second from a fast pen),
      // and each message to the worker cost the page's main thread about 0.1 ms
      // (headless Chromium, two cores): they go together, once a frame, which is
      // as often as the worker draws anyway.
      let rows = [], drives = null, due = 0;
      const flush = () => {
        due = 0;
        worker.postMessage({ type: "frame", rows, drives });
        rows = []; drives = null;
      };
      const soon = () => { if (!due) due = requestAnimationFrame(flush); };
      return {
        mode: "worker",
        setDrives: (chans) => { drives = chans.map(plain); soon(); },
        addWire: (msg) => worker.postMessage({ type: "wire", t_s: msg.t_s, displacement_um: msg.displacement_um, state: msg.state }),
        trailAdd: (r) => { for (const x of r) rows.push(x); soon(); },
        // The old stroke's samples still waiting are dropped with its trail.
        trailClear: () => { rows = []; worker.postMessage({ type: "trail-clear" }); },
        trailResize: (w, h, dpr) => worker.postMessage({ type: "trail-resize", w, h, dpr }),
        plotResize: (w, h, dpr) => worker.postMessage({ type: "plot-resize", w, h, dpr }),
      };
    } catch (e) { /* no module workers or offscreen 2-D contexts here: draw in the page */ }
  }
  const plot = new Plot(plotCanvas, channels), trail = new Trail(trailCanvas);
  return {
    mode: "page",
    setDrives: (chans) => plot.setDrives(chans),
    addWire: (msg) => plot.addWire(msg.t_s, msg.displacement_um, msg.state),
    trailAdd: (rows) => trail.add(rows),
    trailClear: () => trail.clear(),
    trailResize: (w, h, dpr) => trail.resize(w, h, dpr),
    plotResize: (w, h, dpr) => plot.resize(w, h, dpr),
  };
}

// A browser without module workers would load the worker and then fail on its
// imports, after the canvases were handed over; ask first (reading `type` means
// the option is understood).
function moduleWorkers() {
  if (typeof Worker !== "function") return false;
  let understood = false;
  try {
    new Worker("data:text/javascript,", { get type() { understood = true; return "module"; } }).terminate();
  } catch (e) { /* data: workers refused: the answer is still in `understood` */ }
  return understood;
}

// Only what the plot reads, so the message stays small.
const plain = (c) => ({ pulse_frequency_hz: c.pulse_frequency_hz || 0, pulse_width_s: c.pulse_width_s || 0, amplitude: c.amplitude || 0 });
