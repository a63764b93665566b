// A physical output (serial controller, sound card) is driven by one page at a time
// (web/ownership.py): while another page holds it, say so and offer to take it over.
// The banner is made here, so the page's layout needs nothing for it.

let banner = null;

function ensureBanner() {
  if (banner) return banner;
  banner = document.createElement("div");
  banner.id = "output-lease";
  banner.dataset.testid = "output-lease";
  banner.setAttribute("role", "status");
  banner.hidden = true;
  Object.assign(banner.style, { padding: "0.4em 0.8em", background: "#fff3cd", color: "#3d2e00" });
  document.body.prepend(banner);
  return banner;
}

/** Show this page's standing from an {"type": "output"} message; `send` sends a message to the server. */
export function onOutputMessage(msg, send) {
  const b = ensureBanner();
  if (msg.state !== "in_use") { b.hidden = true; b.replaceChildren(); return; }
  const text = document.createElement("span");
  text.textContent = `The actuator is in use by another ${msg.by || "page"}: your strokes are not played on it.`;
  b.replaceChildren(text);
  if (msg.take_over) {
    const button = document.createElement("button");
    button.type = "button";
    button.textContent = "Take over";
    button.dataset.testid = "output-take-over";
    button.addEventListener("click", () => send({ type: "take_over" }));
    b.append(" ", button);
  }
  b.hidden = false;
}
