// The panel's shared time range (lib/timeRange.ts): a jump reaches every listener, a range that
// is no range reaches none, a listener that stopped is not called.
import { describe, expect, it } from "vitest";
import type { TimeRange } from "./historyView";
import { PlotTimeRange } from "./timeRange";

describe("PlotTimeRange", () => {
  it("tells every listening plot, until it stops listening", () => {
    const shared = new PlotTimeRange();
    const a: TimeRange[] = [];
    const b: TimeRange[] = [];
    const stopA = shared.subscribe((r) => a.push(r));
    shared.subscribe((r) => b.push(r));
    expect(shared.current).toBeNull();
    shared.jumpAround(1000, 20);
    expect(a).toEqual([{ from_s: 990, to_s: 1010 }]);
    expect(b).toEqual(a);
    stopA();
    shared.jumpTo({ from_s: 5, to_s: 6 });
    expect(a).toHaveLength(1);
    expect(b).toHaveLength(2);
    expect(shared.current).toEqual({ from_s: 5, to_s: 6 });
  });

  it("ignores a range that ends before it starts", () => {
    const shared = new PlotTimeRange();
    const got: TimeRange[] = [];
    shared.subscribe((r) => got.push(r));
    shared.jumpTo({ from_s: 6, to_s: 6 });
    shared.jumpTo({ from_s: Number.NaN, to_s: 6 });
    expect(got).toEqual([]);
    expect(shared.current).toBeNull();
  });
});
