// The paper's Fig. 5 for the picture being stroked: the picture, its 2-D
// Fourier spectrum (log magnitude, DC centred, from /api/textures/{id}/spectrum)
// with the dominant peak circled and labelled with f_s [cycles/mm] and i_s,
// and the texture map's tiles (f_s per tile) when the picture changes across.

const cache = new Map();
let wanted = null;  // the texture asked for last: a slower earlier fetch must not overwrite it

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
  await drawSpectrum(doc);
  drawTiles(doc);
  return doc;
}

function loadImage(url) {
  return new Promise((ok, bad) => { const im = new Image(); im.onload = () => ok(im); im.onerror = bad; im.src = url; });
}

async function drawSpectrum(doc) {
  const c = document.querySelector("#spectrum"), ctx = c.getContext("2d");
  const im = await loadImage(doc.spectrum_url);
  const [h, w] = doc.crop;
  const s = Math.min(c.width / w, c.height / h);
  const ox = (c.width - w * s) / 2, oy = (c.height - h * s) / 2;
  ctx.fillStyle = "#000"; ctx.fillRect(0, 0, c.width, c.height);
  ctx.imageSmoothingEnabled = false;
  ctx.drawImage(im, ox, oy, w * s, h * s);
  ctx.font = "20px system-ui, sans-serif";
  ctx.fillStyle = "#ddd"; ctx.fillText("log |F|, DC centred", 6, 22);
  if (!doc.peak) return;
  const at = ([x, y]) => [ox + (x + 0.5) * s, oy + (y + 0.5) * s];
  ctx.strokeStyle = "#ff4040"; ctx.lineWidth = 2;
  for (const p of [doc.peak_px, doc.mirror_px]) {
    const [x, y] = at(p);
    ctx.beginPath(); ctx.arc(x, y, 10, 0, 2 * Math.PI); ctx.stroke();
  }
  const [x, y] = at(doc.peak_px);
  const label = `f_s ${doc.spatial_frequency_per_mm.toFixed(3)}/mm`;
  ctx.fillStyle = "#ff8080";
  const tx = Math.min(Math.max(4, x + 10), c.width - ctx.measureText(label).width - 4);
  ctx.fillText(label, tx, Math.min(Math.max(44, y - 14), c.height - 8));
}

function drawTiles(doc) {
  const c = document.querySelector("#tilemap"), ctx = c.getContext("2d");
  ctx.clearRect(0, 0, c.width, c.height);
  const t = doc.tiles, note = document.querySelector("#tilemap-note");
  if (!t) { note.textContent = "–"; return; }
  const f = t.spatial_frequency_per_mm.flat();
  const lo = Math.min(...f), hi = Math.max(...f);
  const varies = hi > 1.2 * lo + 1e-9;
  note.textContent = `${t.rows} × ${t.cols} of ${t.tile_mm[0].toFixed(1)} mm, f_s ${lo.toFixed(2)}–${hi.toFixed(2)} /mm` + (varies ? " (changes across)" : " (uniform)");
  c.dataset.varies = String(varies);
  const cw = c.width / t.cols, ch = c.height / t.rows;
  ctx.font = `${Math.max(12, Math.min(20, cw / 3))}px system-ui, sans-serif`;
  ctx.textAlign = "center"; ctx.textBaseline = "middle";
  for (let r = 0; r < t.rows; r++) for (let k = 0; k < t.cols; k++) {
    const v = t.spatial_frequency_per_mm[r][k];
    // A uniform picture reads as one colour: never stretch less than 20 % of f_s.
    const span = Math.max(hi - lo, 0.2 * hi, 1e-9);
    const u = (v - lo) / span;
    ctx.fillStyle = `hsl(${240 - 200 * u}, 60%, ${35 + 25 * u}%)`;
    ctx.fillRect(k * cw, r * ch, cw - 1, ch - 1);
    if (cw > 28) { ctx.fillStyle = "#fff"; ctx.fillText(v.toFixed(2), k * cw + cw / 2, r * ch + ch / 2); }
  }
}
