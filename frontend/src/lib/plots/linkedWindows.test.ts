// Issue 38 item 14: a window picked on one linked plot is shown by every plot's picker, not
// only drawn. The picker (components/LivePlotView.tsx) shows what `onWindowChange` says.
import { describe, expect, it } from "vitest";
import { setupPlot } from "./plotTestSupport";
import { PlotTimeRange } from "./timeRange";

describe("linked window pickers", () => {
  it("tells the picker of a window followed from another plot, as of one picked on it", () => {
    const a = setupPlot();
    const b = setupPlot();
    const axis = new PlotTimeRange();
    const pickedA: number[] = [];
    const pickedB: number[] = [];
    a.plot.onWindowChange = (ms) => pickedA.push(ms);
    b.plot.onWindowChange = (ms) => pickedB.push(ms);
    // Each plot tells the panel's time axis of its moves and follows the others' (plots/plotWiring.ts).
    const keyA = {};
    const keyB = {};
    axis.subscribe((move) => a.plot.follow(move), keyA);
    axis.subscribe((move) => b.plot.follow(move), keyB);
    a.plot.onMove = (move) => axis.move(move, keyA);
    b.plot.onMove = (move) => axis.move(move, keyB);

    a.plot.setWindow(30_000);
    expect(pickedA).toEqual([30_000]);
    expect(pickedB).toEqual([30_000]); // B's picker follows A's
    b.plot.setWindow(60_000);
    expect(pickedB).toEqual([30_000, 60_000]);
    expect(pickedA).toEqual([30_000, 60_000]); // and back
    // The same window again changes nothing and tells nobody.
    a.plot.setWindow(60_000);
    expect(pickedA).toEqual([30_000, 60_000]);
  });
});
