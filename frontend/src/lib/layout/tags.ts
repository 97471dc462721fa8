/**
 * Layer: pure tag-name helpers (no React, no DOM, no network): a point's label with its tag
 * name, as the panel, the events, the audit and the alarms show it ("DO 3 — gripper close").
 * Keys are the API's `name.index` (0-based: `controlbox_do.2` is DO 3); labels come from the
 * layout (`keyLabel`) or from the service's answer (`labels`), never computed from the index.
 */
import { tagLabel } from "../alarms/alarms";
import { keyLabel } from "./layoutInfo";

export type TagNames = Readonly<Record<string, string>>;

/** "DO 3 — gripper close" for `controlbox_do.2`; the label alone without a name. */
export function pointWords(key: string, tags: TagNames | null | undefined, labels?: TagNames | null): string {
  return tagLabel(labels?.[key] ?? keyLabel(key), tags?.[key]);
}

/** The points of `keys` in words, joined ("DO 3 — gripper close, DO 4"), "—" for none. */
export function pointsWords(keys: readonly string[], tags: TagNames | null | undefined, labels?: TagNames | null): string {
  return keys.length === 0 ? "—" : keys.map((k) => pointWords(k, tags, labels)).join(", ");
}

/** How many names differ between two sets (an empty name counts as none). */
export function tagChanges(before: TagNames, after: TagNames): number {
  const keys = new Set([...Object.keys(before), ...Object.keys(after)]);
  let changed = 0;
  for (const key of keys) if ((before[key] ?? "").trim() !== (after[key] ?? "").trim()) changed++;
  return changed;
}

/**
 * The question before a bit is written, saying what it is and its tag name: "Set bit input
 * register 5 (part present) ON?", "Switch DO 3 (gripper close) OFF?". `label` is the point's
 * label as shown (a register's is its number).
 */
export function bitWriteQuestion(kind: "output" | "register", label: string, tag: string | null | undefined, on: boolean): string {
  const named = tag !== undefined && tag !== null && tag.trim() !== "" ? ` (${tag.trim()})` : "";
  const state = on ? "ON" : "OFF";
  return kind === "register" ? `Set bit input register ${label}${named} ${state}?` : `Switch ${label}${named} ${state}?`;
}

/**
 * The value a click on a bit's toggle asks for: the opposite of what the toggle SHOWS. After a
 * write is confirmed the toggle holds the value written until the robot's frames show it (they
 * come over the stream, the confirmation over HTTP), so the frame's value may still be the old
 * one; asking from it turned "ON, click" into "Switch ON?" again.
 */
export function bitClickRequest(shown: boolean | number | "pending" | null, actual: boolean | null, command: boolean | null): boolean {
  const seen = typeof shown === "boolean" ? shown : null;
  return !(seen ?? actual ?? command ?? false);
}
