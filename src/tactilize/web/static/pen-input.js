// Pen input: Pointer Events with every coalesced sample and its own timestamp.
//
// Each pointermove carries the samples the browser merged into one frame
// (getCoalescedEvents); a 240 Hz pen on a 60 Hz display gives about four.
// They are sent as one batch, at once, not on the next animation frame:
// waiting would add up to a frame of latency.

/** Attach pen input to `surface`; positions are relative to `picture`.
 *  onBatch(rows) gets [[t_ms, x_px, y_px, pressure|null, tilt_x_deg, tilt_y_deg], ...];
 *  onLift() is called when the pen leaves the surface; onHover() at most every
 *  HOVER_MS while a pen or mouse moves over it without touching (the server then
 *  holds the wire ready, so the first touch is felt at once). */
const HOVER_MS = 250;

export function attachPen(surface, picture, { onBatch, onLift, onDown, onHover }) {
  let active = null;  // pointerId of the stroke in progress
  let rect = null;
  let lastHover = -Infinity;

  const row = (ev) => {
    // A mouse has no pressure (browsers report 0.5 while a button is held).
    const p = ev.pointerType === "mouse" ? null : (Number.isFinite(ev.pressure) ? ev.pressure : null);
    return [ev.timeStamp, ev.clientX - rect.left, ev.clientY - rect.top, p, ev.tiltX || 0, ev.tiltY || 0];
  };
  const samplesOf = (ev) => {
    const list = typeof ev.getCoalescedEvents === "function" ? ev.getCoalescedEvents() : [];
    return (list && list.length ? list : [ev]).map(row);
  };

  surface.addEventListener("pointerdown", (ev) => {
    if (active !== null || (ev.pointerType === "mouse" && ev.button !== 0)) return;
    active = ev.pointerId;
    // Capture: strokes that leave the picture keep reporting, so the server sees
    // the pen leave (and stops) instead of a stroke that just ends.
    try { surface.setPointerCapture(ev.pointerId); } catch (e) { /* synthetic pointers */ }
    rect = picture.getBoundingClientRect();
    ev.preventDefault();
    onDown && onDown(ev);
    onBatch([row(ev)]);
  });
  surface.addEventListener("pointermove", (ev) => {
    if (ev.pointerId !== active) {
      if (active === null && onHover && ev.timeStamp - lastHover >= HOVER_MS) {
        lastHover = ev.timeStamp;
        onHover();
      }
      return;
    }
    onBatch(samplesOf(ev));
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
}
