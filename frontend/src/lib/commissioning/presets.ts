/**
 * Layer: the panel's REST calls for output presets (docs/api.md "Output presets") over the typed
 * client of `lib/api/api.ts`, and the pure helpers of its view. No React.
 */
import { API, api, type JsonClient, type PageAnswer } from "../api/api";
import { pageOf } from "./checkout";
import { commandField } from "../layout/layoutInfo";
import type { components } from "../../generated/api";

type Schemas = components["schemas"];
export type Preset = Schemas["Preset"];
export type PresetList = Schemas["PresetList"];
export type PresetChanges = Schemas["PresetChanges"];
export type PresetChange = Schemas["PresetChange"];

const JSON_CONTENT = { "Content-Type": "application/json" } as const;

export class PresetsApi {
  constructor(readonly client: JsonClient) {}

  async list(robot: string): Promise<PageAnswer<PresetList>> {
    return pageOf(await this.client.GET("/api/v1/robots/{name}/presets", { params: { path: { name: robot } } }));
  }

  /** A preset from the command image being sent: all of it, or only the fields named. */
  async saveFromImage(robot: string, name: string, fields: readonly string[] | null): Promise<PageAnswer<Preset>> {
    const body = { name, from_image: true, ...(fields !== null ? { fields: [...fields] } : {}) };
    return pageOf(await this.client.POST("/api/v1/robots/{name}/presets", { params: { path: { name: robot } }, body, headers: JSON_CONTENT }));
  }

  /** A preset made by hand: `{"field.index": value}` (the service checks it whole). */
  async saveItems(robot: string, name: string, items: Readonly<Record<string, boolean | number>>): Promise<PageAnswer<Preset>> {
    const body = { name, items: { ...items } };
    return pageOf(await this.client.POST("/api/v1/robots/{name}/presets", { params: { path: { name: robot } }, body, headers: JSON_CONTENT }));
  }

  async remove(robot: string, preset: string): Promise<PageAnswer<PresetList>> {
    return pageOf(
      await this.client.DELETE("/api/v1/robots/{name}/presets/{preset}", { params: { path: { name: robot, preset } }, headers: JSON_CONTENT }),
    );
  }

  async importText(robot: string, text: string, fileName: string): Promise<PageAnswer<PresetList>> {
    const body = importBody(text, fileName);
    if (body === null) return { ok: false, status: 422, reason: `${fileName}: neither the CSV nor the JSON export` };
    return pageOf(await this.client.POST("/api/v1/robots/{name}/presets/import", { params: { path: { name: robot } }, body, headers: JSON_CONTENT }));
  }

  async changes(robot: string, preset: string): Promise<PageAnswer<PresetChanges>> {
    return pageOf(await this.client.GET("/api/v1/robots/{name}/presets/{preset}/changes", { params: { path: { name: robot, preset } } }));
  }

  async apply(robot: string, preset: string): Promise<PageAnswer<PresetChanges>> {
    return pageOf(
      await this.client.POST("/api/v1/robots/{name}/presets/{preset}/apply", { params: { path: { name: robot, preset } }, headers: JSON_CONTENT }),
    );
  }
}

export const presetsApi = new PresetsApi(api.client);

export function presetsCsvUrl(robot: string): string {
  return `${API}/robots/${encodeURIComponent(robot)}/presets.csv`;
}

export function presetsJsonUrl(robot: string): string {
  return `${API}/robots/${encodeURIComponent(robot)}/presets`;
}

type ImportBody = Schemas["PresetImport"];

/** The import's body from a file: the JSON export (`{"items": [...]}`) or the CSV export. */
export function importBody(text: string, fileName: string): ImportBody | null {
  const trimmed = text.trim();
  if (fileName.toLowerCase().endsWith(".json") || trimmed.startsWith("{")) {
    try {
      const parsed = JSON.parse(trimmed) as { items?: unknown };
      if (!Array.isArray(parsed.items)) return null;
      const items = (parsed.items as Preset[]).filter((p) => !p.builtin).map((p) => ({ name: p.name, items: p.items }));
      return { items };
    } catch {
      return null;
    }
  }
  return trimmed.startsWith("preset,") ? { csv: text } : null;
}

function valueWords(value: boolean | number): string {
  return typeof value === "boolean" ? (value ? "on" : "off") : String(value);
}

/** The confirmation's list: "Register in 0: off → on". */
export function changeLines(changes: readonly PresetChange[]): string[] {
  return changes.map((c) => `${c.label}: ${valueWords(c.from)} → ${valueWords(c.to)}`);
}

/** "Register in 0–3 = 1100"-like short words of a preset's items: how many, and of what. */
export function presetWords(preset: Preset): string {
  const labels = Object.values(preset.labels);
  const shown = labels.slice(0, 4).join(", ");
  return labels.length > 4 ? `${shown} … (${labels.length} values)` : shown;
}

const BIT_WORDS: Readonly<Record<string, boolean>> = { on: true, off: false, "1": true, "0": false, true: true, false: false };

/** Every output's label (as the checkout and the presets name them) to its key, lower case. */
function outputKeys(): Map<string, { key: string; analog: boolean }> {
  const keys = new Map<string, { key: string; analog: boolean }>();
  for (const name of ["controlbox_do", "tool_do", "analog_output", "bit_input_registers"] as const) {
    commandField(name).channels.forEach((label, i) => {
      const entry = { key: `${name}.${i}`, analog: name === "analog_output" };
      keys.set(entry.key, entry);
      keys.set((name === "bit_input_registers" ? label.replace("Register", "Register in") : label).toLowerCase(), entry);
    });
  }
  return keys;
}

export type ParsedItems = { readonly ok: true; readonly items: Record<string, boolean | number> } | { readonly ok: false; readonly reason: string };

/**
 * A preset typed by hand: `DO 3 = on, Register in 12 = off, AO 0 = 12.5` (a comma or a new
 * line between entries; a label or a key; on/off, 1/0 or true/false for bits, a number for AO).
 */
export function parsePresetItems(text: string): ParsedItems {
  const keys = outputKeys();
  const items: Record<string, boolean | number> = {};
  for (const entry of text.split(/[,\n;]/).map((e) => e.trim()).filter((e) => e !== "")) {
    const [name = "", raw = "", ...rest] = entry.split("=").map((part) => part.trim());
    const point = keys.get(name.toLowerCase());
    if (point === undefined || rest.length > 0) return { ok: false, reason: `“${entry}”: not an output = value (DO 3 = on, Register in 12 = off, AO 0 = 12.5)` };
    if (point.analog) {
      const value = Number(raw);
      if (raw === "" || !Number.isFinite(value)) return { ok: false, reason: `“${entry}”: an analog output takes a number` };
      items[point.key] = value;
    } else {
      const bit = BIT_WORDS[raw.toLowerCase()];
      if (bit === undefined) return { ok: false, reason: `“${entry}”: a bit is on or off` };
      items[point.key] = bit;
    }
  }
  if (Object.keys(items).length === 0) return { ok: false, reason: "no values: DO 3 = on, Register in 12 = off…" };
  return { ok: true, items };
}
