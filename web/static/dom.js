// Building the page without innerHTML: every value from the API is set as text, never
// parsed as markup.

const SVG_NS = "http://www.w3.org/2000/svg";

function apply(el, attrs) {
  for (const [key, value] of Object.entries(attrs || {})) {
    if (value === undefined || value === null || value === false) continue;
    if (key.startsWith("on")) el.addEventListener(key.slice(2), value);
    else if (key === "class") el.setAttribute("class", value);
    else if (key === "text") el.textContent = value;
    else if (key in el && !(el instanceof SVGElement)) el[key] = value;
    else el.setAttribute(key, value === true ? "" : value);
  }
}

function append(el, children) {
  for (const child of children.flat(Infinity)) {
    if (child === undefined || child === null || child === false) continue;
    el.append(child instanceof Node ? child : document.createTextNode(String(child)));
  }
}

/** An HTML element: h("button", {onclick}, "text", child…). */
export function h(tag, attrs, ...children) {
  const el = document.createElement(tag);
  apply(el, attrs);
  append(el, children);
  return el;
}

/** An SVG element. */
export function s(tag, attrs, ...children) {
  const el = document.createElementNS(SVG_NS, tag);
  apply(el, attrs);
  append(el, children);
  return el;
}

/** Replaces the children of `el`. */
export function fill(el, ...children) {
  el.replaceChildren();
  append(el, children);
  return el;
}

/** `0x` and four (or `width`) hex digits. */
export function hex(value, width = 4) {
  return "0x" + Number(value).toString(16).toUpperCase().padStart(width, "0");
}

/** A labelled section with a heading. */
export function section(title, ...children) {
  const id = "s-" + title.toLowerCase().replace(/[^a-z0-9]+/g, "-");
  return h("section", { class: "card", "aria-labelledby": id },
    h("h2", { id }, title), ...children);
}

/** A two-column list of facts. */
export function facts(rows) {
  return h("dl", { class: "facts" },
    rows.map(([k, v]) => [h("dt", {}, k), h("dd", {}, v)]));
}

/** A status line that says what went wrong (role="alert" so screen readers hear it). */
export function errorLine(err) {
  return h("p", { class: "error", role: "alert" }, String(err.message || err));
}

/**
 * A lamp for a bit: a filled or hollow circle (the shape, not only the colour, tells) and,
 * unless `short`, "on"/"off" as text; `label` names it for screen readers.
 */
export function lamp(on, label, short = "") {
  const el = h("span", { class: "lamp", role: "img" });
  setLamp(el, on, label, short);
  return el;
}

/** Sets a lamp made by [`lamp`] to `on`. */
export function setLamp(el, on, label, short = "") {
  const text = on ? "on" : "off";
  el.dataset.on = on ? "true" : "false";
  el.setAttribute("aria-label", `${label}: ${text}`);
  el.title = `${label}: ${text}`;
  el.textContent = short || text;
}

/**
 * A modal dialog (`<dialog>`: the browser keeps the focus inside it and Escape closes it)
 * with a title, a message and buttons, for actions that need an explicit confirmation.
 * `ask(message, buttons)` shows them and resolves with the `value` of the button pressed, ""
 * when the dialog is closed with Escape or `close()`. It leaves the page when it closes.
 */
export class Modal {
  constructor(id, title) {
    this.message = h("div", { id: `${id}-message`, class: "modal-message" });
    this.buttons = h("div", { class: "row modal-buttons" });
    this.el = h("dialog", { id, class: "modal", "aria-labelledby": `${id}-title`, "aria-describedby": `${id}-message` },
      h("h2", { id: `${id}-title` }, title), this.message, this.buttons);
    this.pending = null;
    // The focus goes back where it was (the button that opened the dialog) when it closes.
    const opener = document.activeElement;
    this.el.addEventListener("close", () => {
      this.answer("");
      this.el.remove();
      if (opener && opener.isConnected && opener.focus) opener.focus();
    });
    document.body.append(this.el);
    this.el.showModal();
  }

  /**
   * Shows `message` (nodes) and `buttons` ([{label, value, id, class, focus}]; the one with
   * `focus` has the focus, else the last); resolves with the value of the button pressed.
   */
  ask(message, buttons) {
    this.answer("");
    // Closed meanwhile (Escape while the action ran): nothing more to ask.
    if (!this.el.open) return Promise.resolve("");
    fill(this.message, message);
    const made = buttons.map((b) => h("button", { type: "button", id: b.id, class: b.class, value: b.value, onclick: () => this.answer(b.value) }, b.label));
    fill(this.buttons, made);
    (made[buttons.findIndex((b) => b.focus)] || made[made.length - 1]).focus();
    return new Promise((resolve) => {
      this.pending = resolve;
    });
  }

  /** Shows `text` as the state of the action (the buttons disabled meanwhile). */
  busy(text) {
    for (const b of this.buttons.querySelectorAll("button")) b.disabled = true;
    this.buttons.append(h("span", { class: "muted", role: "status" }, text));
  }

  answer(value) {
    const resolve = this.pending;
    this.pending = null;
    if (resolve) resolve(value);
  }

  close() {
    if (this.el.open) this.el.close();
  }
}
