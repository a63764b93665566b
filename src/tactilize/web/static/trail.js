// The pen's trail over the picture: one line per stroke, as thick as the pen
// presses.  Works on any 2-D canvas context, in the page or in the drawing
// worker (drawing.js); rows are drawn once a frame, not once a batch.

const nextFrame = typeof requestAnimationFrame === "function" ? (f) => requestAnimationFrame(f) : (f) => setTimeout(f, 16);

export class Trail {
  constructor(canvas) {
    this.canvas = canvas;
    this.ctx = canvas.getContext("2d");
    this.dpr = 1;
    this.last = null;   // the previous sample drawn [x, y] (CSS px)
    this.rows = [];     // samples waiting for the next frame
    this.frame = 0;
  }

  /** The surface's size [CSS px] and the device pixel ratio; clears the trail. */
  resize(wPx, hPx, dpr) {
    this.dpr = dpr;
    this.canvas.width = Math.round(wPx * dpr);
    this.canvas.height = Math.round(hPx * dpr);
    this.last = null;
  }

  /** A new stroke: clear what the last one drew. */
  clear() {
    this.rows = [];
    this.ctx.clearRect(0, 0, this.canvas.width, this.canvas.height);
    this.last = null;
  }

  /** Samples [[t_ms, x_px, y_px, pressure|null, ...], ...] of the stroke in progress. */
  add(rows) {
    for (const r of rows) this.rows.push(r);
    if (!this.frame) this.frame = nextFrame(() => { this.frame = 0; this.draw(); });
  }

  draw() {
    const { ctx, dpr } = this;
    ctx.strokeStyle = "rgba(220, 40, 40, 0.85)"; ctx.lineCap = "round";
    for (const [, x, y, p] of this.rows) {
      if (this.last) {
        ctx.lineWidth = (1 + 3 * (p === null ? 0.5 : p)) * dpr;
        ctx.beginPath(); ctx.moveTo(this.last[0] * dpr, this.last[1] * dpr); ctx.lineTo(x * dpr, y * dpr); ctx.stroke();
      }
      this.last = [x, y];
    }
    this.rows = [];
  }
}
