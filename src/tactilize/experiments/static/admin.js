// The experimenter's view: sessions and progress, refreshed every few seconds, and the exports.
const token = new URLSearchParams(location.search).get("token") || "";
const q = token ? `?token=${encodeURIComponent(token)}` : "";
const api = new URL("api/admin/", document.baseURI);
for (const [id, path] of [["csv", "export.csv"], ["json", "export.json"], ["analysis", "analysis"]]) {
  document.getElementById(id).href = new URL(path + q, api);
}

async function refresh() {
  const res = await fetch(new URL("sessions" + q, api));
  const doc = await res.json();
  const msg = document.getElementById("message");
  if (!res.ok) { msg.textContent = doc.error; msg.hidden = false; return; }
  msg.hidden = true;
  document.getElementById("title").textContent = `${doc.protocol.title} (v${doc.protocol.version}, ${doc.protocol.sha256.slice(0, 12)})`;
  const done = doc.sessions.filter((s) => s.completed_at).length;
  document.getElementById("summary").textContent = `${doc.sessions.length} sessions, ${done} complete`;
  const body = document.getElementById("sessions");
  body.replaceChildren(...doc.sessions.map((s) => {
    const tr = document.createElement("tr");
    for (const v of [s.participant + (s.simulated ? " (sim)" : ""), s.participant_number, `${s.trials_done} / ${s.trials_total}`,
      s.stroke_samples, s.calibrated ? "yes" : "no", s.created_at, s.completed_at || ""]) {
      const td = document.createElement("td"); td.textContent = String(v); tr.append(td);
    }
    return tr;
  }));
}
refresh();
setInterval(refresh, 5000);
