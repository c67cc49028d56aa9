// The SII summary: the fixed area and the STRINGS and GENERAL categories (spec-notes
// §sii.fixed, §sii.categories).

import { hex } from "./dom.js";

const PROTOCOLS = [[0, "AoE"], [1, "EoE"], [2, "CoE"], [3, "FoE"], [4, "SoE"], [5, "VoE"]];

/** Parses the SII image (`bytes`, a Uint8Array) into [label, text] rows. */
export function siiSummary(bytes) {
  const word = (w) => (2 * w + 1 < bytes.length ? bytes[2 * w] | (bytes[2 * w + 1] << 8) : 0);
  const dword = (w) => (word(w) | (word(w + 1) << 16)) >>> 0;
  const protocols = word(0x1c);
  const rows = [
    ["Vendor ID", hex(dword(0x08), 8)],
    ["Product code", hex(dword(0x0a), 8)],
    ["Revision", hex(dword(0x0c), 8)],
    ["Serial number", String(dword(0x0e))],
    ["Configured alias", String(word(0x04))],
    ["Mailbox out (SM0)", word(0x19) ? `${hex(word(0x18))}, ${word(0x19)} bytes` : "none"],
    ["Mailbox in (SM1)", word(0x1b) ? `${hex(word(0x1a))}, ${word(0x1b)} bytes` : "none"],
    ["Mailbox protocols", PROTOCOLS.filter(([bit]) => protocols & (1 << bit)).map(([, n]) => n).join(" ") || "none"],
    ["EEPROM size", `${(word(0x3e) + 1) / 8} KiB`],
    ["SII version", String(word(0x3f))],
  ];
  const strings = [];
  let general = null;
  // Categories from word 0x40: type, size in words, data; END is 0xFFFF.
  for (let w = 0x40; 2 * w + 3 < bytes.length;) {
    const type = word(w);
    const size = word(w + 1);
    if (type === 0xffff) break;
    const start = 2 * (w + 2);
    const data = bytes.subarray(start, Math.min(bytes.length, start + 2 * size));
    if (type === 10 && data.length) {
      let at = 1;
      for (let i = 0; i < data[0] && at < data.length; i++) {
        const len = data[at];
        strings.push(String.fromCharCode(...data.subarray(at + 1, at + 1 + len)));
        at += 1 + len;
      }
    } else if (type === 30 && data.length >= 16) {
      general = data;
    }
    w += 2 + size;
  }
  const str = (i) => (i > 0 && i <= strings.length ? strings[i - 1] : "–");
  if (general) {
    rows.push(["Name", str(general[3])], ["Order code", str(general[2])], ["Group", str(general[0])]);
    const coe = general[5];
    const details = [[0, "SDO"], [1, "SDO Information"], [2, "PDO assign"], [3, "PDO configuration"], [5, "complete access"]]
      .filter(([bit]) => coe & (1 << bit)).map(([, n]) => n);
    rows.push(["CoE details", details.join(", ") || "none"]);
    const ebus = (general[12] | (general[13] << 8)) << 16 >> 16;
    rows.push(["E-bus current", `${ebus} mA`]);
  }
  return rows;
}
