// lib/'s shape (docs/architecture.md "Frontend"): every module in a folder of its concern, and
// every test beside the code it tests, so it imports a module of its own folder (other folders'
// code only as a dependency). A module dropped into lib/ itself, or a test of one folder's code
// filed in another, fails here.
import { readdirSync, readFileSync, statSync } from "node:fs";
import { dirname, join, resolve } from "node:path";
import { fileURLToPath } from "node:url";
import { describe, expect, it } from "vitest";

const LIB = join(resolve(dirname(fileURLToPath(import.meta.url))), "lib");
const FOLDERS = readdirSync(LIB).filter((name) => statSync(join(LIB, name)).isDirectory());
const IMPORT = /(?:import|export)\s[^'"]*?from\s*["']([^"']+)["']/g;

/** The modules of its own folder a test imports (its test support among them: a plot's tests
 * drive a `LivePlot` through `plotTestSupport.ts`). */
function ownImports(text: string): string[] {
  return [...text.matchAll(IMPORT)].map((m) => m[1] ?? "").filter((spec) => /^\.\/[^/]+$/.test(spec));
}

describe("lib/", () => {
  it("holds folders only, one per concern", () => {
    const loose = readdirSync(LIB).filter((name) => !FOLDERS.includes(name));
    expect(loose).toEqual([]);
    expect(FOLDERS.length).toBeGreaterThan(5);
  });

  it("files every test beside code it tests", () => {
    const astray: string[] = [];
    for (const folder of FOLDERS) {
      for (const name of readdirSync(join(LIB, folder)).filter((n) => n.endsWith(".test.ts"))) {
        if (ownImports(readFileSync(join(LIB, folder, name), "utf8")).length === 0) astray.push(`${folder}/${name}`);
      }
    }
    expect(astray).toEqual([]);
  });

  it("sees a test that imports only another folder's code (so the check above can fail)", () => {
    expect(ownImports('import { LiveData } from "../stream/liveData";\nimport type { Frame } from "../../generated/layout";')).toEqual([]);
    expect(ownImports('import { alarms } from "./alarms";')).toEqual(["./alarms"]);
  });
});
