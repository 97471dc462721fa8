// The panel's one time axis (lib/plots/timeRange.ts): a move reaches every listener but the plot that
// made it, a range that is no range reaches none, a listener that stopped is not called, a jump
// is remembered until a move leaves it; the cursor is told to every cursor listener once per change.
import { describe, expect, it } from "vitest";
import { PlotTimeRange, linkPlot, type PlotMove } from "./timeRange";

describe("PlotTimeRange", () => {
  it("tells every listening plot but the one that moved, until it stops listening", () => {
    const shared = new PlotTimeRange();
    const a: PlotMove[] = [];
    const b: PlotMove[] = [];
    const keyA = {};
    const stopA = shared.subscribe((m) => a.push(m), keyA);
    shared.subscribe((m) => b.push(m));
    expect(shared.current).toBeNull();
    shared.jumpTo({ from_s: 990, to_s: 1010 });
    expect(a).toEqual([{ kind: "jump", range: { from_s: 990, to_s: 1010 } }]);
    expect(b).toEqual(a);
    shared.move({ kind: "window", window_ms: 30_000 }, keyA); // A's own move: not told back to A
    expect(a).toHaveLength(1);
    expect(b.at(-1)).toEqual({ kind: "window", window_ms: 30_000 });
    stopA();
    shared.jumpTo({ from_s: 5, to_s: 6 });
    expect(a).toHaveLength(1);
    expect(b).toHaveLength(3);
    expect(shared.current).toEqual({ from_s: 5, to_s: 6 });
    expect(shared.listenerCount).toBe(1);
  });

  it("back to live and a new range leave the jump's range", () => {
    const shared = new PlotTimeRange();
    const got: PlotMove[] = [];
    shared.subscribe((m) => got.push(m));
    shared.jumpTo({ from_s: 5, to_s: 6 });
    shared.backToLive();
    expect(got.at(-1)).toEqual({ kind: "live" });
    expect(shared.current).toBeNull();
    shared.jumpTo({ from_s: 5, to_s: 6 });
    shared.move({ kind: "range", range: { from_s: 4, to_s: 6 } });
    expect(shared.current).toBeNull();
  });

  it("ignores a range that ends before it starts", () => {
    const shared = new PlotTimeRange();
    const got: PlotMove[] = [];
    shared.subscribe((m) => got.push(m));
    shared.jumpTo({ from_s: 6, to_s: 6 });
    shared.jumpTo({ from_s: Number.NaN, to_s: 6 });
    shared.move({ kind: "range", range: { from_s: 7, to_s: 6 } });
    expect(got).toEqual([]);
    expect(shared.current).toBeNull();
  });

  it("links a plot both ways, and unlinks it", () => {
    const shared = new PlotTimeRange();
    const followed: PlotMove[] = [];
    const plot = { onMove: null as ((m: PlotMove) => void) | null, follow: (m: PlotMove) => followed.push(m) };
    const other: PlotMove[] = [];
    shared.subscribe((m) => other.push(m));
    const unlink = linkPlot(shared, plot);
    plot.onMove?.({ kind: "live" }); // the plot's own move: told to the others, not back to it
    expect(other).toEqual([{ kind: "live" }]);
    expect(followed).toEqual([]);
    shared.move({ kind: "window", window_ms: 120_000 });
    expect(followed).toEqual([{ kind: "window", window_ms: 120_000 }]);
    unlink();
    expect(plot.onMove).toBeNull();
    shared.backToLive();
    expect(followed).toHaveLength(1);
  });

  it("tells the cursor's time once per change, null when it goes", () => {
    const shared = new PlotTimeRange();
    const got: (number | null)[] = [];
    const stop = shared.subscribeCursor((t) => got.push(t));
    shared.setCursor(1000);
    shared.setCursor(1000);
    shared.setCursor(Number.NaN);
    shared.setCursor(null);
    expect(got).toEqual([1000, null]);
    expect(shared.cursorTime).toBeNull();
    stop();
    shared.setCursor(5);
    expect(got).toHaveLength(2);
  });

  it("opens at a URL's range: a plot that links while it is shown follows it at once", () => {
    const range = { from_s: 100, to_s: 200 };
    const shared = new PlotTimeRange().openAt(range);
    expect(shared.current).toEqual(range);
    const first: PlotMove[] = [];
    const plot = { onMove: null as ((m: PlotMove) => void) | null, follow: (m: PlotMove) => first.push(m) };
    linkPlot(shared, plot);
    expect(first).toEqual([{ kind: "jump", range }]);
    // Back to live: a plot linked later opens live.
    shared.backToLive();
    const later: PlotMove[] = [];
    shared.subscribe((m) => later.push(m));
    expect(later).toEqual([]);
    // No range, or none that is one: the axis opens live.
    expect(new PlotTimeRange().openAt(null).current).toBeNull();
    expect(new PlotTimeRange().openAt({ from_s: 5, to_s: 5 }).current).toBeNull();
  });
});
