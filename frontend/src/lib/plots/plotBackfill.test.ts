// A ring view's start from the recording (lib/plots/plotBackfill.ts): the points of an answer before
// the ring's oldest frame (each bucket's min and max, a missing bucket a break), and a live plot
// opened on a window the ring does not fill yet asks the recording once and draws the window
// whole at once; a ring that holds the window asks nothing.
import { describe, expect, it } from "vitest";
import type { RangeData, TimeRange } from "./historyView";
import { backfillPoints } from "./plotBackfill";
import { LivePlot } from "./plotting";
import { ChannelMap, JOINT_PLOTS, tracesOf } from "./plots";
import { SampleRing } from "../stream/ringBuffer";
import { fakeBackend, historyAnswerOf } from "./plotTestSupport";
import { fakeTimer } from "./timerTestSupport";

const spec = JOINT_PLOTS[0]!;
const T0 = 1_700_000_000_000;

describe("backfillPoints", () => {
  const traces = tracesOf(spec);

  it("gives each bucket before the ring its minimum and maximum, shifted as the plot's x", () => {
    const answer = historyAnswerOf({ from_s: 100, to_s: 104 }); // buckets at 100 s and 102 s, 2 s wide
    const { xs, ys } = backfillPoints(answer, traces, 103_000, 60_000);
    expect(xs[0]).toEqual([100_000 - 60_000, 101_000 - 60_000, 102_000 - 60_000, 103_000 - 60_000]);
    expect(ys[0]).toEqual([10, 20, 10, 20]);
    expect(ys[5]).toEqual([15, 25, 15, 25]);
    // Only what lies before the ring's first point.
    expect(backfillPoints(answer, traces, 101_000, 0).xs[0]).toEqual([100_000, 101_000]);
    // Only from the bucket holding the window's start on.
    expect(backfillPoints(answer, traces, Infinity, 0, 102_500).xs[0]).toEqual([102_000, 103_000]);
  });

  it("breaks the line where a bucket is missing, and leaves out a signal the answer lacks", () => {
    const answer = historyAnswerOf({ from_s: 100, to_s: 104 }, { t: [100, 106], points: 2, bucket_s: 2 });
    const { xs, ys } = backfillPoints(answer, traces, Infinity, 0);
    expect(xs[0]).toEqual([100_000, 101_000, 102_000, 106_000, 107_000]);
    expect(ys[0]).toEqual([10, 20, null, 10, 20]);
    const none = backfillPoints({ ...answer, series: [] }, traces, Infinity, 0);
    expect(none.xs[0]).toEqual([]);
  });
});

describe("a live plot opened on a window the ring does not fill", () => {
  function setup() {
    const backend = fakeBackend({ plotlyReact: true });
    const fetches: { range: TimeRange; points: number; resolve: (d: RangeData) => void }[] = [];
    const { timer } = fakeTimer();
    const channels = new ChannelMap([spec]);
    const ring = new SampleRing(32_768, channels.channelCount);
    const plot = new LivePlot(spec, ring, channels, backend, {
      window_ms: 10_000,
      theme: "light",
      readOnly: false,
      history: {
        fetchRange: (range, points) => new Promise<RangeData>((resolve) => fetches.push({ range, points, resolve })),
        timer,
        debounce_ms: 200,
        now_ms: () => ring.newestTime() ?? T0,
      },
    });
    const el = { dataset: {}, clientWidth: 880 } as unknown as HTMLElement;
    plot.mount(el);
    const push = (t_ms: number) => ring.push(t_ms, [1, 1, 1, 1, 1, 1]);
    const tz = new Date().getTimezoneOffset() * 60_000;
    const lastData = () => backend.calls.filter((c) => c.op === "react").at(-1)!.args[1] as { x: number[] }[];
    return { plot, push, fetches, lastData, tz };
  }

  it("asks the recording once for the window's start and draws it in front of the ring", async () => {
    const { plot, push, fetches, lastData, tz } = setup();
    for (let t = T0 - 3000; t <= T0; t += 10) push(t);
    plot.update(0);
    expect(fetches.map((f) => f.range)).toEqual([{ from_s: (T0 - 10_000) / 1000, to_s: (T0 - 3000) / 1000 }]);
    // Buckets as wide as the ring view's (200 a window): 140 for the 7 s.
    expect(fetches[0]!.points).toBe(140);
    expect(lastData()[0]!.x[0]).toBe(T0 - 3000 - tz);
    const range = fetches[0]!.range;
    fetches[0]!.resolve({ range, answer: historyAnswerOf(range), events: [] });
    await new Promise((r) => setTimeout(r, 0));
    expect(plot.hasWork()).toBe(true);
    plot.update(1);
    expect(lastData()[0]!.x[0]).toBe(T0 - 10_000 - tz);
    // The cursor reads the answer where the ring holds nothing.
    expect(plot.valuesAt(T0 - 9000)[0]).toEqual({ min: 10, max: 20 });
    expect(plot.valuesAt(T0 - 1000)[0]).toEqual({ value: 1 });
    // Once per window: the next frames ask nothing more.
    push(T0 + 10);
    plot.update(2);
    expect(fetches).toHaveLength(1);
    // A drawing whole again later keeps the window: nothing of the answer before its start.
    push(T0 + 4000);
    plot.setPointerInside(true);
    expect(lastData()[0]!.x[0]).toBeGreaterThanOrEqual(T0 - 6000 - 2000 - tz); // the bucket holding the start
    // Once the ring holds the window, the answer goes (nor does the cursor read it).
    for (let t = T0 + 4010; t <= T0 + 8000; t += 10) push(t);
    plot.setPointerInside(false);
    expect(plot.valuesAt(T0 - 9000)[0]).toBeNull();
  });

  it("drawn before the first frame, asks at the first frames' update", () => {
    const { plot, push, fetches } = setup();
    plot.update(0); // an empty ring: nothing to judge yet
    expect(fetches).toEqual([]);
    push(T0);
    expect(plot.hasWork()).toBe(true);
    plot.update(1);
    expect(fetches.map((f) => f.range)).toEqual([{ from_s: (T0 - 10_000) / 1000, to_s: T0 / 1000 }]);
  });

  it("asks nothing when the ring holds the window", () => {
    const { plot, push, fetches } = setup();
    for (let t = T0 - 12_000; t <= T0; t += 10) push(t);
    plot.update(0);
    expect(fetches).toEqual([]);
    push(T0 + 10);
    plot.update(1);
    expect(fetches).toEqual([]);
  });
});
