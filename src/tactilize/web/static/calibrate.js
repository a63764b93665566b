// Calibration: how many millimetres one CSS pixel measures on this screen.
//
// A CSS pixel is 1/96 inch only by definition (docs/references.md, section 5); real screens
// differ.  The user matches an on-screen card to a real ID-1 card (85.60 mm wide).
// What is stored is mm per *device* pixel, so that browser zoom (which changes
// devicePixelRatio and the size of a CSS pixel together) keeps the calibration.

import { constants } from "./constants.js";

export const CARD_MM = constants.card_mm;
export const DEFAULT_MM_PER_PX = constants.default_mm_per_px;
// The believable display scales [mm per CSS px], the server's rule (tactilize.pen.display).
const [MIN_MM_PER_PX, MAX_MM_PER_PX] = constants.mm_per_px_range;
// A phone's CSS pixel is about 0.16 mm: docs/references.md, section 5 (CSS pixel on phones).
// Only the calibration dialog's starting point on a phone, never a value used
// uncalibrated: the page says it is not calibrated until the user saves.
export const PHONE_MM_PER_PX = 0.16;
// Narrower than this [CSS px], the card is held upright and its short side matched:
// its long side (85.60 mm, over 500 phone pixels) does not fit a phone's width.
const UPRIGHT_BELOW_PX = 600;

/** A touch screen the size of a phone (the calibration prompt's audience). */
export function likelyPhone() {
  return matchMedia("(pointer: coarse)").matches && Math.min(screen.width, screen.height) < UPRIGHT_BELOW_PX;
}
const KEY = "tactilize.calibration.v1";

/** The calibrated mm per CSS pixel for the current zoom, or the 1/96 inch default. */
export function mmPerPx() {
  const c = load();
  if (!c) return DEFAULT_MM_PER_PX;
  return c.mm_per_device_px * (window.devicePixelRatio || 1);
}

/** Is the stored value a calibration (true) or the default (false)? */
export function isCalibrated() { return load() !== null; }

function load() {
  try {
    const c = JSON.parse(localStorage.getItem(KEY) || "null");
    if (c && Number.isFinite(c.mm_per_device_px) && c.mm_per_device_px > 0) return c;
  } catch (e) { /* a corrupt entry is the same as none */ }
  return null;
}

/** Keep a calibration given in mm per CSS pixel at the current zoom. */
export function save(mmPerCssPx) {
  if (!(Number.isFinite(mmPerCssPx) && mmPerCssPx >= MIN_MM_PER_PX && mmPerCssPx <= MAX_MM_PER_PX)) {
    throw new RangeError(`mm per CSS px must be in [${MIN_MM_PER_PX}, ${MAX_MM_PER_PX}], got ${mmPerCssPx}`);
  }
  const dpr = window.devicePixelRatio || 1;
  localStorage.setItem(KEY, JSON.stringify({ mm_per_device_px: mmPerCssPx / dpr, dpr, at: new Date().toISOString() }));
}

export function reset() { localStorage.removeItem(KEY); }

/** Wire the dialog: slider and number for the card width, or mm/px directly.
 *  onChange(mmPerPx) is called after a save or a reset. */
export function setupDialog(dialog, openButton, onChange) {
  const card = dialog.querySelector("#card");
  const range = dialog.querySelector("#card-range");
  const cardPx = dialog.querySelector("#card-px");
  const mmInput = dialog.querySelector("#mm-per-px");
  let side = CARD_MM[0];  // the card's side matched to the on-screen card's width [mm]
  const orient = () => {
    const upright = window.innerWidth < UPRIGHT_BELOW_PX;
    side = upright ? CARD_MM[1] : CARD_MM[0];
    card.style.aspectRatio = upright ? `${CARD_MM[1]} / ${CARD_MM[0]}` : `${CARD_MM[0]} / ${CARD_MM[1]}`;
    dialog.querySelector("#card-side").textContent = side.toFixed(2);
    dialog.querySelector("#card-how").textContent = upright ? "upright" : "lying";
  };
  const show = (mm) => {
    const w = side / mm;
    card.style.width = `${w}px`;
    range.value = String(w);
    cardPx.value = w.toFixed(1);
    mmInput.value = mm.toFixed(5);
  };
  range.addEventListener("input", () => show(side / Number(range.value)));
  cardPx.addEventListener("input", () => {
    const w = Number(cardPx.value);
    if (w > 0) { card.style.width = `${w}px`; range.value = String(w); mmInput.value = (side / w).toFixed(5); }
  });
  mmInput.addEventListener("input", () => {
    const mm = Number(mmInput.value);
    if (mm > 0) { const w = side / mm; card.style.width = `${w}px`; range.value = String(w); cardPx.value = w.toFixed(1); }
  });
  openButton.addEventListener("click", () => {
    orient();
    show(!isCalibrated() && likelyPhone() ? PHONE_MM_PER_PX : mmPerPx());
    dialog.showModal();
  });
  dialog.addEventListener("close", () => {
    if (dialog.returnValue === "save") {
      const mm = Number(mmInput.value);
      try { save(mm); } catch (e) { alert(e.message); return; }
    } else if (dialog.returnValue === "reset") {
      reset();
    } else {
      return;
    }
    onChange(mmPerPx());
  });
  // Zoom changes devicePixelRatio; the stored mm per device px keeps the size right.
  let dpr = window.devicePixelRatio;
  const watch = () => {
    matchMedia(`(resolution: ${dpr}dppx)`).addEventListener("change", () => {
      dpr = window.devicePixelRatio; onChange(mmPerPx()); watch();
    }, { once: true });
  };
  watch();
}
