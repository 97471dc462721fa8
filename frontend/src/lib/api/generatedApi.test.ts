// The frontend's API types are generated from the service's OpenAPI document (make codegen):
// this fails when src/generated/api.ts is not what the committed document gives, and checks
// (at compile time, `npm run typecheck`) that the contract's frame and command shapes are the
// layout's, so the two generated files cannot drift apart.
import { readFileSync } from "node:fs";
import { describe, expect, expectTypeOf, it } from "vitest";
import { API_TS_PATH, OPENAPI_PATH, generateApiTs } from "../../../scripts/generate-api.mjs";
import type { components } from "../../generated/api";
import type { CommandImage, CommandPatch, Frame } from "../../generated/layout";
import { EVENT_KINDS, type EventKind } from "./protocol";

type Schemas = components["schemas"];

// Each generation runs openapi-typescript over the whole document: about a second alone, over
// 5 s (Vitest's default) on a loaded machine.
describe("src/generated/api.ts", { timeout: 60_000 }, () => {
  const documentText = readFileSync(OPENAPI_PATH, "utf8");

  it("is what docs/openapi.json generates (else run `make codegen`)", async () => {
    const expected = await generateApiTs(documentText);
    const current = readFileSync(API_TS_PATH, "utf8");
    expect(current === expected, "src/generated/api.ts is stale: run `make codegen`").toBe(true);
  });

  it("changes when the document changes (so the check above can fail)", async () => {
    const document = JSON.parse(documentText) as { components: { schemas: Record<string, unknown> } };
    document.components.schemas.StaleCheckProbe = { type: "object", properties: { x: { type: "integer" } } };
    const changed = await generateApiTs(JSON.stringify(document));
    expect(changed).not.toBe(await generateApiTs(documentText));
    expect(changed).toContain("StaleCheckProbe");
  });

  it("writes a schema that refers to itself as a JSON value TypeScript accepts, and refuses others", async () => {
    const document = (schemas: Record<string, unknown>) =>
      JSON.stringify({ openapi: "3.1.0", info: { title: "t", version: "1" }, paths: {}, components: { schemas } });
    const json = {
      anyOf: [
        { type: "boolean" },
        { type: "number" },
        { type: "string" },
        { type: "null" },
        { type: "array", items: { $ref: "#/components/schemas/Any" } },
        { type: "object", additionalProperties: { $ref: "#/components/schemas/Any" } },
      ],
    };
    const text = await generateApiTs(document({ Any: json }));
    expect(text).toContain("export type JsonValue =");
    expect(text).toMatch(/Any: JsonValue;/);
    const tree = { type: "object", properties: { children: { type: "array", items: { $ref: "#/components/schemas/Tree" } } } };
    await expect(generateApiTs(document({ Tree: tree }))).rejects.toThrow(/Tree refers to itself/);
  });

  it("describes no shape as empty (every answer has its schema)", () => {
    expect(documentText).not.toMatch(/"schema":\s*\{\s*\}/);
  });
});

describe("the contract and the layout", () => {
  it("agree on the frame, the command image and the patch", () => {
    expectTypeOf<keyof Schemas["Frame"]>().toEqualTypeOf<keyof Frame | "extra">();
    expectTypeOf<Schemas["Frame"]>().toExtend<Frame>();
    expectTypeOf<keyof Schemas["CommandImage"]>().toEqualTypeOf<keyof CommandImage>();
    expectTypeOf<Schemas["CommandImage"]>().toExtend<CommandImage>();
    expectTypeOf<keyof Schemas["CommandPatch"]>().toEqualTypeOf<keyof CommandPatch>();
    expectTypeOf<CommandPatch>().toExtend<Schemas["CommandPatch"]>();
  });

  it("name every event kind in the filter", () => {
    expectTypeOf<(typeof EVENT_KINDS)[number]>().toEqualTypeOf<EventKind>();
    expect(new Set(EVENT_KINDS).size).toBe(EVENT_KINDS.length);
  });
});
