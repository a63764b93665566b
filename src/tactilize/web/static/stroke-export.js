// The last stroke as a file, and the drive it makes as a file.
//
// Self-contained: app.js tells it when a stroke starts and hands it every batch
// of samples; this module keeps the samples that fall on the shown surface, in
// the stroke file's units (t_s from the stroke's first sample, x_mm and y_mm
// from the top-left corner of the picture's own copy, y down, pressure), and
// owns the block #stroke-export of the page.  "Download stroke" saves them as
// CSV; "Export this stroke" posts them to /api/export/stroke, which runs them
// through the pen server's path and answers the file in the chosen format.

const state = {
  texture: null, mmPerPx: 0.2645833, widthMm: 0, heightMm: 0, areaWMm: 0, areaHMm: 0,
  rows: [], t0: null, recording: [],
};

/** A stroke starts on `texture` shown `widthMm` x `heightMm` at `mmPerPx`,
 *  repeated over an area of `areaWMm` x `areaHMm` (the surface shown when the
 *  picture fills the screen; one copy when left out).  The last stroke is
 *  forgotten here, not at its second sample: a stroke that never touches the
 *  picture leaves nothing to download rather than the stroke before it. */
export function beginStroke(texture, mmPerPx, widthMm, heightMm, areaWMm = widthMm, areaHMm = heightMm) {
  Object.assign(state, {
    texture, mmPerPx, widthMm, heightMm, areaWMm: Math.max(areaWMm, widthMm), areaHMm: Math.max(areaHMm, heightMm),
    rows: [], t0: null, recording: [],
  });
}

/** Forget the last stroke (another picture, another view). */
export function forget(texture = null) { Object.assign(state, { texture, rows: [], t0: null, recording: [] }); }

/** Page rows [t_ms, x_px, y_px, pressure|null, ...] of the stroke in progress. */
export function addSamples(rows) {
  for (const [tMs, xPx, yPx, p] of rows) {
    const xs = xPx * state.mmPerPx, ys = yPx * state.mmPerPx;
    if (!(xs >= 0 && ys >= 0 && xs < state.areaWMm && ys < state.areaHMm)) continue;  // the pen off the surface
    // Every copy is the same picture: a sample on a copy is where it falls on
    // the picture itself, which is what the export's map and the CSV's reader know.
    const x = xs % state.widthMm, y = ys % state.heightMm;
    if (state.t0 === null) state.t0 = tMs;
    const t = (tMs - state.t0) / 1000;
    const last = state.recording[state.recording.length - 1];
    if (last && t <= last[0]) continue;  // times must increase
    state.recording.push([t, x, y, p === null || p === undefined ? null : p]);
  }
  if (state.recording.length >= 2) state.rows = state.recording;
}

/** The last stroke with at least two samples: {texture, samples: [[t_s, x_mm, y_mm, pressure], ...]}. */
export function lastStroke() { return { texture: state.texture, samples: state.rows }; }

function strokeCsv(rows) {
  const f = (v, d) => (v === null ? "" : v.toFixed(d));
  return "t_s,x_mm,y_mm,pressure\n" + rows.map(([t, x, y, p]) => `${f(t, 6)},${f(x, 4)},${f(y, 4)},${f(p, 4)}`).join("\n") + "\n";
}

function save(blob, name) {
  const a = document.createElement("a");
  a.href = URL.createObjectURL(blob); a.download = name;
  document.body.append(a); a.click(); a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 10000);
}

/** Wire up the block: `getProfile()` names the profile the page uses. */
export async function setupStrokeExport(root, getProfile) {
  const status = root.querySelector("[data-testid=stroke-export-status]");
  const select = root.querySelector("[data-testid=stroke-format]");
  const say = (text, bad = false) => { status.textContent = text; status.className = bad ? "bad" : ""; };
  try {
    const formats = await (await fetch("/api/export/formats")).json();
    for (const f of formats) {
      const o = document.createElement("option"); o.value = f.name; o.textContent = f.name; o.title = f.description; select.append(o);
    }
    select.value = "ahap";
  } catch (e) { say(`formats: ${e.message}`, true); }
  root.querySelector("[data-testid=stroke-download]").addEventListener("click", () => {
    const s = lastStroke();
    if (s.samples.length < 2) { say("stroke the picture first", true); return; }
    save(new Blob([strokeCsv(s.samples)], { type: "text/csv" }), `stroke-${s.texture}.csv`);
    say(`${s.samples.length} samples, ${s.samples[s.samples.length - 1][0].toFixed(2)} s`);
  });
  root.querySelector("[data-testid=stroke-export-button]").addEventListener("click", async () => {
    const s = lastStroke();
    if (s.samples.length < 2) { say("stroke the picture first", true); return; }
    say("exporting…");
    try {
      const r = await fetch("/api/export/stroke", {
        method: "POST", headers: { "Content-Type": "application/json" },
        body: JSON.stringify({ texture: s.texture, format: select.value, profile: getProfile(), samples: s.samples }),
      });
      if (!r.ok) { const b = await r.json().catch(() => ({})); say(b.error || `export failed (${r.status})`, true); return; }
      const name = (/filename="([^"]+)"/.exec(r.headers.get("Content-Disposition") || "") || [])[1] || `stroke.${select.value}`;
      save(await r.blob(), name);
      say(`exported ${name}`);
    } catch (e) { say(`export failed: ${e.message}`, true); }
  });
}
