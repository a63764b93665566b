// The page's drawing, off its main thread: the plot and the pen's trail on
// OffscreenCanvases handed over by drawing.js.  The main thread only posts what
// changed; it stays free for the pen's raw updates and the drives coming back.

import { Plot } from "./plot.js";
import { Trail } from "./trail.js";

let plot = null, trail = null;

self.onmessage = (ev) => {
  const m = ev.data;
  if (m.type === "init") {
    plot = new Plot(m.plot, m.channels);
    trail = new Trail(m.trail);
    return;
  }
  if (!plot) return;
  if (m.type === "frame") {
    if (m.drives) plot.setDrives(m.drives);
    if (m.rows.length) trail.add(m.rows);
  } else if (m.type === "wire") plot.addWire(m.t_s, m.displacement_um, m.state);
  else if (m.type === "trail-clear") trail.clear();
  else if (m.type === "trail-resize") trail.resize(m.w, m.h, m.dpr);
  else if (m.type === "plot-resize") plot.resize(m.w, m.h, m.dpr);
};
