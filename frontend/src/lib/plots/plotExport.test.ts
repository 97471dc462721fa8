// What a plot's "Export the view" covers (issue 38): the range its time axis shows, the window's
// front from the recording included (a 2 min view exported 9 s, what reached the page since it
// opened), and "nothing recorded from … to …" where the recording has no frame.
import { describe, expect, it } from "vitest";
import { LivePlot } from "./plotting";
import { backfilledFrom_ms, nothingRecordedWords, unrecordedStart } from "./plotExport";
import type { RangeData, TimeRange } from "./historyView";
import { ChannelMap, JOINT_PLOTS } from "./plots";
import { SampleRing } from "../stream/ringBuffer";
import { fakeBackend, historyAnswerOf } from "./plotTestSupport";
import { fakeTimer } from "./timerTestSupport";

const T0 = 1_795_500_000_000; // ms since the epoch
const spec = JOINT_PLOTS[0]!;
const settle = () => new Promise((r) => setTimeout(r, 0));

/** A panel plot of a 2 min window, 9 s after the page opened (its ring holds 9 s). */
function twoMinutesNineSecondsIn() {
  const channels = new ChannelMap([spec]);
  const ring = new SampleRing(32_768, channels.channelCount);
  const fetches: { range: TimeRange; resolve: (d: RangeData) => void }[] = [];
  const { timer } = fakeTimer();
  const plot = new LivePlot(spec, ring, channels, fakeBackend({ plotlyReact: true }), {
    window_ms: 120_000,
    theme: "light",
    readOnly: false,
    history: {
      fetchRange: (range: TimeRange) => new Promise<RangeData>((resolve) => fetches.push({ range, resolve })),
      timer,
      debounce_ms: 200,
      now_ms: () => ring.newestTime() ?? T0,
    },
  });
  plot.mount({ dataset: {}, clientWidth: 880 } as unknown as HTMLElement);
  for (let t = T0 - 9000; t <= T0; t += 10) ring.push(t, [1, 1, 1, 1, 1, 1]);
  plot.update(0);
  return { plot, fetches };
}

describe("the export of a plot's view", () => {
  it("covers the whole window the axis shows once the recording filled its front", async () => {
    const { plot, fetches } = twoMinutesNineSecondsIn();
    // The one request: the window's 111 s before the ring's oldest frame.
    expect(fetches.map((f) => f.range)).toEqual([{ from_s: (T0 - 120_000) / 1000, to_s: (T0 - 9000) / 1000 }]);
    expect(plot.visibleRange()).toEqual({ from_s: (T0 - 9000) / 1000, to_s: T0 / 1000 });
    const f = fetches[0]!;
    f.resolve({ range: f.range, answer: historyAnswerOf(f.range), events: [] });
    await settle();
    plot.update(1);
    expect(plot.visibleRange()).toEqual({ from_s: (T0 - 120_000) / 1000, to_s: T0 / 1000 });
    expect(plot.unrecorded()).toBeNull();
  });

  it("says what of the window the recording has nothing of", async () => {
    const { plot, fetches } = twoMinutesNineSecondsIn();
    const f = fetches[0]!;
    f.resolve({ range: f.range, answer: historyAnswerOf(f.range, { frames: 0, t: [], t_last: [], series: [] }), events: [] });
    await settle();
    plot.update(1);
    // Nothing drawn before the ring: the axis, and the export, are the ring's 9 s.
    expect(plot.visibleRange()).toEqual({ from_s: (T0 - 9000) / 1000, to_s: T0 / 1000 });
    expect(plot.unrecorded()).toEqual({ from_s: (T0 - 120_000) / 1000, to_s: (T0 - 9000) / 1000 });
  });

  it("finds the unrecorded start of a range and says it in words", () => {
    const range = { from_s: 1000, to_s: 1120 };
    const answer = { frames: 0, t: [], mode: "buckets" as const, bucket_s: 1 };
    expect(unrecordedStart(range, answer)).toEqual(range);
    expect(unrecordedStart(range, { ...answer, frames: 50, t: [1030, 1031] })).toEqual({ from_s: 1000, to_s: 1030 });
    expect(unrecordedStart(range, { ...answer, frames: 50, t: [1001, 1002] })).toBeNull();
    expect(unrecordedStart(range, { frames: 3, t: [1000.2], mode: "raw", bucket_s: null })).toBeNull();
    const clock = (ms: number) => `t${ms / 1000}`;
    expect(nothingRecordedWords({ from_s: 1000, to_s: 1111 }, clock)).toBe("nothing recorded from t1000 to t1111");
    expect(nothingRecordedWords({ from_s: 0, to_s: 60 })).toMatch(/^nothing recorded from \d{4}-\d\d-\d\d \d\d:\d\d:\d\d to \d{4}-\d\d-\d\d \d\d:\d\d:\d\d$/);
    expect(backfilledFrom_ms(T0, 120_000, { frames: 10, t: [(T0 - 125_000) / 1000] })).toBe(T0 - 120_000);
    expect(backfilledFrom_ms(T0, 120_000, { frames: 10, t: [(T0 - 60_000) / 1000] })).toBe(T0 - 60_000);
    expect(backfilledFrom_ms(T0, 120_000, { frames: 0, t: [] })).toBeNull();
  });
});
