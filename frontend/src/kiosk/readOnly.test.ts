// The kiosk is read-only by construction: walking its import graph from KioskApp must never
// reach a write control (src/panel/), the REST module (lib/api/api.ts) or the write logic
// (lib/writes/writes.ts). A change that wires a write into the kiosk fails here.
import { existsSync, readFileSync } from "node:fs";
import { dirname, join, relative, resolve } from "node:path";
import { fileURLToPath } from "node:url";
import { describe, expect, it } from "vitest";
import { isKioskPath } from "../lib/common/route";

const SRC = resolve(dirname(fileURLToPath(import.meta.url)), "..");
// The REST client, the alarm actions, lib/commissioning/ (checkout and presets, which write) and
// lib/writes/ but for the words of who holds control (controlSession.ts, pure), which the kiosk shows.
const FORBIDDEN = [
  /^panel\//,
  /^lib\/api\/api\.ts$/,
  /^lib\/alarms\/alarmsApi\.ts$/,
  /^lib\/writes\/(?!controlSession\.ts$)/,
  /^lib\/commissioning\//,
];

function resolveImport(from: string, spec: string): string | null {
  if (!spec.startsWith(".")) return null; // packages
  const base = resolve(dirname(from), spec);
  for (const candidate of [base, `${base}.ts`, `${base}.tsx`, join(base, "index.ts"), join(base, "index.tsx")]) {
    if (existsSync(candidate) && /\.(ts|tsx|css)$/.test(candidate)) return candidate;
  }
  return null;
}

function importGraph(entry: string): Set<string> {
  const seen = new Set<string>();
  const queue = [entry];
  const pattern = /(?:import|export)\s[^'"]*?from\s*["']([^"']+)["']|import\s*\(\s*["']([^"']+)["']\s*\)|import\s+["']([^"']+)["']/g;
  while (queue.length > 0) {
    const file = queue.pop() as string;
    if (seen.has(file)) continue;
    seen.add(file);
    if (!/\.(ts|tsx)$/.test(file)) continue;
    const text = readFileSync(file, "utf8");
    for (const m of text.matchAll(pattern)) {
      const spec = m[1] ?? m[2] ?? m[3];
      if (spec === undefined) continue;
      const target = resolveImport(file, spec);
      if (target !== null) queue.push(target);
    }
  }
  return seen;
}

describe("kiosk", () => {
  it("imports no write control, no REST module and no write logic", () => {
    const files = [...importGraph(join(SRC, "kiosk", "KioskApp.tsx"))].map((f) => relative(SRC, f));
    expect(files).toContain("components/StateBadge.tsx");
    expect(files).toContain("lib/stream/stream.ts");
    // The alarm banner is there, read-only (acknowledging goes through lib/alarms/alarmsApi.ts).
    expect(files).toContain("components/AlarmBanner.tsx");
    const forbidden = files.filter((f) => FORBIDDEN.some((p) => p.test(f)));
    expect(forbidden).toEqual([]);
  });

  it("the fleet overview imports no write control either (it only reads the robot list)", () => {
    const files = [...importGraph(join(SRC, "fleet", "FleetApp.tsx"))].map((f) => relative(SRC, f));
    expect(files).toContain("lib/fleet/fleet.ts");
    expect(files.filter((f) => /^panel\//.test(f))).toEqual([]);
  });

  it("the walker does find the panel's writes (so the check above means something)", () => {
    const files = [...importGraph(join(SRC, "panel", "PanelApp.tsx"))].map((f) => relative(SRC, f));
    expect(files).toContain("lib/writes/writes.ts");
    expect(files).toContain("lib/api/api.ts");
    expect(files).toContain("lib/commissioning/checkout.ts");
    expect(files).toContain("panel/OutputToggle.tsx");
  });

  it("routes /kiosk to the kiosk and everything else to the panel", () => {
    const main = readFileSync(join(SRC, "main.tsx"), "utf8");
    expect(main).toContain('import("./kiosk/KioskApp")');
    expect(main).toContain('import("./fleet/FleetApp")');
    expect(isKioskPath("/kiosk")).toBe(true);
    expect(isKioskPath("/kiosk/")).toBe(true);
    expect(isKioskPath("/")).toBe(false);
    expect(isKioskPath("/kiosky")).toBe(false);
  });
});
