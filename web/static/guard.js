// Guardrails around writes: a confirmation naming slave, object and value before anything
// is sent, and the read-only mode (every write control drawn but disabled) for a caller
// without the write role.

import { h, facts, Modal } from "./dom.js";

/** The title a disabled write control shows: why it is disabled, and what would enable it. */
export const NEEDS_WRITE = "Needs a write token: this session can only read (Token button)";

/** The confirmation open now, closed when the view changes (leaving means no). */
let open = null;

/**
 * Draws `control` (a button, input, select or form) as a write control: enabled with the
 * write role, else disabled with [`NEEDS_WRITE`] as its title. Returns it.
 */
export function writeControl(control, app) {
  control.classList.add("write");
  if (app.canWrite()) return control;
  const parts = control.matches("button, input, select, textarea") ? [control] : [...control.querySelectorAll("button, input, select, textarea")];
  for (const el of parts) {
    el.disabled = true;
    el.title = NEEDS_WRITE;
  }
  control.title = NEEDS_WRITE;
  control.classList.add("needs-write");
  return control;
}

/**
 * Asks before a write: a modal `<dialog>` (`#confirm-dialog`) titled `title` that says
 * `intro` and lists `rows` ([label, text]: the slave, the object, the value), with the
 * buttons `confirm` (`#confirm-ok`) and Cancel (`#confirm-cancel`, which has the focus).
 * Resolves true only when `confirm` is pressed; Cancel, Escape or leaving the view: false.
 */
export async function confirmWrite({ title, intro, rows, confirm, danger = false }) {
  closeConfirmation();
  const modal = new Modal("confirm-dialog", title);
  open = modal;
  const choice = await modal.ask([h("p", {}, intro), facts(rows), h("p", { class: "muted" }, "Nothing is sent before you confirm.")], [
    { label: confirm, value: "confirm", id: "confirm-ok", class: danger ? "write danger" : "write" },
    { label: "Cancel", value: "", id: "confirm-cancel", focus: true },
  ]);
  modal.close();
  if (open === modal) open = null;
  return choice === "confirm";
}

/** Closes the open confirmation, if any, as a Cancel. */
export function closeConfirmation() {
  if (open) open.close();
  open = null;
}

/** A slave as a confirmation names it: `3: EL7031 (station 0x03EC)`. */
export function slaveText(position, name, station) {
  const hexStation = station === undefined ? "" : ` (station 0x${Number(station).toString(16).toUpperCase().padStart(4, "0")})`;
  return `${position}: ${name || "(no name)"}${hexStation}`;
}
