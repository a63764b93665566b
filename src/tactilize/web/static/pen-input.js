// Pen input at the device's rate, every sample once, each with its own timestamp.
//
// Chromium aligns `pointermove` to animation frames (a move waits up to a frame,
// 11 ms p50 on a bare page); `pointerrawupdate` arrives as the device reports,
// 0.7 ms p50: docs/references.md, section 9 (pointermove in Chromium, pointerrawupdate in Chromium);
// coalesced samples: docs/references.md, section 5 (pointer events).
// So: raw updates where the browser has them (Chromium, secure contexts, which
// loopback is), `pointermove` with its coalesced samples elsewhere.  Never both
// for one stroke, and a sample older than the last one sent, or the same time
// and place again, is dropped, so no sample is ever sent twice.

/** The input this browser gives: "pointerrawupdate" or "pointermove". */
export const INPUT = typeof window !== "undefined" && "onpointerrawupdate" in window ? "pointerrawupdate" : "pointermove";

/** Attach pen input to `surface`; positions are relative to `picture`.
 *  onBatch(rows) gets [[t_ms, x_px, y_px, pressure|null, tilt_x_deg, tilt_y_deg], ...] in CSS px
 *  (rowsInMm and samplesMessage below make the socket's message of them);
 *  onLift() is called when the pen leaves the surface; onHover() at most every
 *  HOVER_MS while a pen or mouse moves over it without touching (the server then
 *  holds the wire ready, so the first touch is felt at once). */
const HOVER_MS = 250;

export function attachPen(surface, picture, { onBatch, onLift, onDown, onHover }, input = INPUT) {
  let active = null;  // pointerId of the stroke in progress
  let rect = null;
  let lastHover = -Infinity;
  let last = [-Infinity, NaN, NaN];  // newest sample sent in this stroke: t [ms], x, y [CSS px]

  const row = (ev) => {
    // A mouse has no pressure (browsers report 0.5 while a button is held).
    const p = ev.pointerType === "mouse" ? null : (Number.isFinite(ev.pressure) ? ev.pressure : null);
    return [ev.timeStamp, ev.clientX - rect.left, ev.clientY - rect.top, p, ev.tiltX || 0, ev.tiltY || 0];
  };
  const send = (events) => {
    const rows = [];
    for (const e of events) {
      const r = row(e);
      if (r[0] < last[0] || (r[0] === last[0] && r[1] === last[1] && r[2] === last[2])) continue;
      last = r;
      rows.push(r);
    }
    if (rows.length) onBatch(rows);
  };
  const samplesOf = (ev) => {
    const list = typeof ev.getCoalescedEvents === "function" ? ev.getCoalescedEvents() : [];
    return list && list.length ? list : [ev];
  };

  surface.addEventListener("pointerdown", (ev) => {
    if (active !== null || (ev.pointerType === "mouse" && ev.button !== 0)) return;
    active = ev.pointerId;
    last = [-Infinity, NaN, NaN];
    // Capture: strokes that leave the picture keep reporting, so the server sees
    // the pen leave (and stops) instead of a stroke that just ends.
    try { surface.setPointerCapture(ev.pointerId); } catch (e) { /* synthetic pointers */ }
    rect = picture.getBoundingClientRect();
    ev.preventDefault();
    onDown && onDown(ev);
    send([ev]);
  });
  const move = (ev) => {
    if (ev.pointerId === active) send(samplesOf(ev));
  };
  surface.addEventListener(input, move);
  surface.addEventListener("pointermove", (ev) => {
    // The stroke's samples are read by move() (as raw updates, where the
    // browser has them: then these are the same samples again); only hover here.
    if (ev.pointerId === active) return;
    if (active === null && onHover && ev.timeStamp - lastHover >= HOVER_MS) {
      lastHover = ev.timeStamp;
      onHover();
    }
  });
  const end = (ev) => {
    if (ev.pointerId !== active) return;
    active = null;
    onLift();
  };
  for (const type of ["pointerup", "pointercancel", "lostpointercapture"]) surface.addEventListener(type, end);
  // Touch scrolling and the context menu would steal strokes.
  surface.addEventListener("contextmenu", (ev) => ev.preventDefault());
  window.addEventListener("scroll", () => { if (active !== null) rect = picture.getBoundingClientRect(); }, { passive: true });
  return { input, reposition: () => { if (active !== null) rect = picture.getBoundingClientRect(); } };
}

// The pen socket's one sample message, the same from both pages (parsed on the
// server by tactilize.web.rows.pen_batch; docs/serve.md, "The WebSocket protocol"):
// positions in millimetres on the picture as shown, so the server needs no page's
// scale, and a batch id the page chooses (the experiment stores each batch once by it).

/** Rows [t_ms, x_px, y_px, ...] in CSS px to millimetres at `mmPerPx` (the page's calibration). */
export function rowsInMm(rows, mmPerPx) {
  return rows.map((r) => [r[0], r[1] * mmPerPx, r[2] * mmPerPx, ...r.slice(3)]);
}

/** The sample message: `batch` the page's id for it, `rowsMm` from rowsInMm, `fields` the page's own
 *  (the experiment's trial and image). */
export function samplesMessage(batch, rowsMm, fields = {}) {
  return { type: "samples", batch: String(batch), ...fields, samples: rowsMm };
}
