// The panel's shared time range (lib/timeRange.ts): a jump reaches every listener, a range that
// is no range reaches none, a listener that stopped is not called, the way back to live names
// the range it leaves.
import { describe, expect, it } from "vitest";
import type { TimeRange } from "./historyView";
import { PlotTimeRange, type SharedTimeEvent } from "./timeRange";

const jumps = (events: SharedTimeEvent[]): TimeRange[] => events.filter((e) => e.kind === "jump").map((e) => e.range);

describe("PlotTimeRange", () => {
  it("tells every listening plot, until it stops listening", () => {
    const shared = new PlotTimeRange();
    const a: SharedTimeEvent[] = [];
    const b: SharedTimeEvent[] = [];
    const stopA = shared.subscribe((e) => a.push(e));
    shared.subscribe((e) => b.push(e));
    expect(shared.current).toBeNull();
    shared.jumpTo({ from_s: 990, to_s: 1010 });
    expect(jumps(a)).toEqual([{ from_s: 990, to_s: 1010 }]);
    expect(b).toEqual(a);
    stopA();
    shared.jumpTo({ from_s: 5, to_s: 6 });
    expect(a).toHaveLength(1);
    expect(jumps(b)).toHaveLength(2);
    expect(shared.current).toEqual({ from_s: 5, to_s: 6 });
  });

  it("back to live names the range it leaves, once", () => {
    const shared = new PlotTimeRange();
    const got: SharedTimeEvent[] = [];
    shared.subscribe((e) => got.push(e));
    shared.backToLive(); // no jump yet: nothing to leave
    expect(got).toEqual([]);
    shared.jumpTo({ from_s: 5, to_s: 6 });
    shared.backToLive();
    expect(got.at(-1)).toEqual({ kind: "live", range: { from_s: 5, to_s: 6 } });
    expect(shared.current).toBeNull();
    shared.backToLive();
    expect(got).toHaveLength(2);
  });

  it("ignores a range that ends before it starts", () => {
    const shared = new PlotTimeRange();
    const got: SharedTimeEvent[] = [];
    shared.subscribe((e) => got.push(e));
    shared.jumpTo({ from_s: 6, to_s: 6 });
    shared.jumpTo({ from_s: Number.NaN, to_s: 6 });
    expect(got).toEqual([]);
    expect(shared.current).toBeNull();
  });
});
