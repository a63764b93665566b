// The paper's Fig. 5 for the picture being stroked: the picture, its 2-D
// Fourier spectrum (log magnitude, DC centred, from /api/textures/{id}/spectrum)
// with the dominant peak circled and labelled with f_s [cycles/mm] and i_s,
// and the texture map's tiles (f_s per tile) when the picture changes across.

const cache = new Map();
let wanted = null;  // the texture asked for last: a slower earlier fetch must not overwrite it
let shown = null;   // the document drawn last, drawn again at a new size
// The labels' size on screen [CSS px], whatever the canvas is shown at: the canvas
// is drawn at its displayed size times devicePixelRatio, so text never shrinks
// with the panel (drawn at 256 px and shown at 120, a 20 px label was 9 px).
export const LABEL_CSS_PX = 14;

/** Size a canvas's drawing buffer to its box; returns canvas px per CSS px. */
function fit(c, aspect) {
  const cssW = c.clientWidth || c.width;
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(64, Math.round(cssW * dpr)), h = Math.round(w / aspect);
  if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
  return c.width / cssW;
}

/** Draw the last figure again (after a resize). */
export async function redrawSpectrum() {
  if (!shown) return;
  await drawSpectrum(shown);
  drawTiles(shown);
}

/** Fetch (once per texture) and draw Fig. 5 into the page's figure. */
export async function showSpectrum(texture) {
  if (!texture) return null;
  wanted = texture.id;
  let doc = cache.get(texture.id);
  if (!doc) {
    const r = await fetch(`/api/textures/${encodeURIComponent(texture.id)}/spectrum`);
    if (!r.ok) throw new Error(`spectrum: ${r.status}`);
    doc = await r.json();
    cache.set(texture.id, doc);
  }
  if (wanted !== texture.id) return null;
  const fig = document.querySelector("#spectrum-figure");
  fig.dataset.id = texture.id;
  document.querySelector("#spectrum-image").src = texture.url;
  document.querySelector("#spectrum-name").textContent = texture.name;
  document.querySelector("#spectrum-fs").textContent = doc.peak ? doc.spatial_frequency_per_mm.toFixed(3) : "none";
  document.querySelector("#spectrum-is").textContent = doc.spectral_intensity.toFixed(3);
  shown = doc;
  await drawSpectrum(doc);
  drawTiles(doc);
  return doc;
}

function loadImage(url) {
  return new Promise((ok, bad) => { const im = new Image(); im.onload = () => ok(im); im.onerror = bad; im.src = url; });
}

async function drawSpectrum(doc) {
  const c = document.querySelector("#spectrum"), ctx = c.getContext("2d");
  if (!doc.image) doc.image = await loadImage(doc.spectrum_url);
  const im = doc.image;
  const k = fit(c, 1);
  const [h, w] = doc.crop;
  const s = Math.min(c.width / w, c.height / h);
  const ox = (c.width - w * s) / 2, oy = (c.height - h * s) / 2;
  ctx.fillStyle = "#000"; ctx.fillRect(0, 0, c.width, c.height);
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(im, ox, oy, w * s, h * s);
  const fontPx = LABEL_CSS_PX * k;
  ctx.font = `${fontPx}px system-ui, sans-serif`;
  ctx.textBaseline = "alphabetic";
  ctx.fillStyle = "#ddd"; ctx.fillText("log |F|", 4 * k, 4 * k + fontPx);
  delete c.dataset.label;
  if (!doc.peak) return;
  const at = ([x, y]) => [ox + (x + 0.5) * s, oy + (y + 0.5) * s];
  ctx.strokeStyle = "#ff4040"; ctx.lineWidth = 2 * k;
  for (const p of [doc.peak_px, doc.mirror_px]) {
    const [x, y] = at(p);
    ctx.beginPath(); ctx.arc(x, y, 8 * k, 0, 2 * Math.PI); ctx.stroke();
  }
  const [x, y] = at(doc.peak_px);
  const label = `f_s ${doc.spatial_frequency_per_mm.toFixed(3)}/mm`;
  const m = ctx.measureText(label);
  const tw = m.width, asc = m.actualBoundingBoxAscent || fontPx * 0.8, desc = m.actualBoundingBoxDescent || fontPx * 0.2;
  const tx = Math.min(Math.max(2 * k, x + 10 * k), c.width - tw - 2 * k);
  const ty = Math.min(Math.max(2 * fontPx + 8 * k, y - 12 * k), c.height - desc - 2 * k);
  // A dark plate under the label: readable on any part of the spectrum.
  ctx.fillStyle = "rgba(0, 0, 0, .6)";
  ctx.fillRect(tx - 2 * k, ty - asc - 2 * k, tw + 4 * k, asc + desc + 4 * k);
  ctx.fillStyle = "#ff9090";
  ctx.fillText(label, tx, ty);
  // Where the label is, in CSS px from the canvas's corner (for tests and tools).
  c.dataset.label = JSON.stringify({ font_css_px: fontPx / k, x: tx / k, y: (ty - asc) / k, w: tw / k, h: (asc + desc) / k });
}

function drawTiles(doc) {
  const c = document.querySelector("#tilemap"), ctx = c.getContext("2d");
  const scale = fit(c, 4 / 3);
  ctx.clearRect(0, 0, c.width, c.height);
  const t = doc.tiles, note = document.querySelector("#tilemap-note");
  if (!t) { note.textContent = "–"; return; }
  const f = t.spatial_frequency_per_mm.flat();
  const lo = Math.min(...f), hi = Math.max(...f);
  const varies = hi > 1.2 * lo + 1e-9;
  note.textContent = `${t.rows} × ${t.cols} of ${t.tile_mm[0].toFixed(1)} mm, f_s ${lo.toFixed(2)}–${hi.toFixed(2)} /mm` + (varies ? " (changes across)" : " (uniform)");
  c.dataset.varies = String(varies);
  const cw = c.width / t.cols, ch = c.height / t.rows;
  ctx.font = `${Math.max(11, Math.min(LABEL_CSS_PX, cw / scale / 3.5)) * scale}px system-ui, sans-serif`;
  ctx.textAlign = "center"; ctx.textBaseline = "middle";
  for (let r = 0; r < t.rows; r++) for (let k = 0; k < t.cols; k++) {
    const v = t.spatial_frequency_per_mm[r][k];
    // A uniform picture reads as one colour: never stretch less than 20 % of f_s.
    const span = Math.max(hi - lo, 0.2 * hi, 1e-9);
    const u = (v - lo) / span;
    ctx.fillStyle = `hsl(${240 - 200 * u}, 60%, ${35 + 25 * u}%)`;
    ctx.fillRect(k * cw, r * ch, cw - 1, ch - 1);
    if (cw > 28 * scale) { ctx.fillStyle = "#fff"; ctx.fillText(v.toFixed(2), k * cw + cw / 2, r * ch + ch / 2); }
  }
}
