// The way from a live plot into the history plot (lib/historyLink.ts).
import { describe, expect, it } from "vitest";
import { HistoryLink, type HistoryRequest } from "./historyLink";

describe("HistoryLink", () => {
  it("hands a live plot's range to the listening history view, and to none after it stopped", () => {
    const link = new HistoryLink();
    const request: HistoryRequest = { specId: "plot-joint-position", range: { from_s: 10, to_s: 20 } };
    expect(link.show(request)).toBe(false);
    const got: HistoryRequest[] = [];
    const stop = link.listen((r) => got.push(r));
    expect(link.show(request)).toBe(true);
    expect(got).toEqual([request]);
    stop();
    expect(link.show(request)).toBe(false);
    expect(got).toHaveLength(1);
  });
});
