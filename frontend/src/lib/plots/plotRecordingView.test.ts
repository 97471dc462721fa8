// A view of the recording's data side (lib/plots/plotRecordingView.ts): the range and the points it
// asks for, how often a moving window asks again, its requests and refresh through a timer, and
// the traces of a drawing (the answer's envelopes, the ring's newest samples not yet recorded).
import { describe, expect, it } from "vitest";
import type { HistoryAnswer, RangeData, TimeRange } from "./historyView";
import {
  MOVING_REFRESH_MAX_MS,
  MOVING_REFRESH_MIN_MS,
  PlotRecording,
  historyTraces,
  movingRefresh_ms,
  nowOnFrames,
  pointsWanted,
  rangeWanted,
  type DrawnPlot,
} from "./plotRecordingView";
import { ChannelMap, JOINT_PLOTS, TCP_PLOTS, tracesOf } from "./plots";
import { SampleRing } from "../stream/ringBuffer";
import { historyAnswerOf } from "./plotTestSupport";
import { fakeTimer } from "./timerTestSupport";

const T0 = 1_795_500_000_000; // ms since the epoch
const joints = JOINT_PLOTS[0]!;

describe("what a view of the recording asks for", () => {
  it("about a point per pixel of the plotting area; a default while the width is not known", () => {
    expect(pointsWanted(joints, 880)).toBe(880 - 64 - 16);
    const velocity = TCP_PLOTS.find((p) => p.id === "plot-tcp-velocity")!;
    expect(pointsWanted(velocity, 880)).toBe(880 - 64 - 64);
    expect(pointsWanted(joints, undefined)).toBe(1000);
    expect(pointsWanted(joints, 0)).toBe(50); // the service's floor
  });

  it("a fixed view its own range; a moving one its span (the ring its window) ending now", () => {
    expect(rangeWanted({ kind: "fixed", from_ms: 5, to_ms: 9 }, T0, 10_000)).toEqual({ from: 5, to: 9 });
    expect(rangeWanted({ kind: "moving", span_ms: 900_000 }, T0, 10_000)).toEqual({ from: T0 - 900_000, to: T0 });
    expect(rangeWanted({ kind: "ring" }, T0, 10_000)).toEqual({ from: T0 - 10_000, to: T0 });
  });

  it("now is the newest frame while frames come, the clock when there are none or they are old", () => {
    expect(nowOnFrames(T0, T0 + 500)).toBe(T0);
    expect(nowOnFrames(T0, T0 + 60_000)).toBe(T0 + 60_000);
    expect(nowOnFrames(null, T0)).toBe(T0);
  });

  it("a moving window asks again when a bucket has filled, within bounds", () => {
    expect(movingRefresh_ms(3_600_000, 800)).toBe(4500);
    expect(movingRefresh_ms(900_000, 800)).toBe(MOVING_REFRESH_MIN_MS);
    expect(movingRefresh_ms(7 * 24 * 3_600_000, 800)).toBe(MOVING_REFRESH_MAX_MS);
  });
});

describe("a plot's requests to the recording", () => {
  it("asks in seconds, debounced unless at once; stopped, nothing more is delivered", async () => {
    const { timer, due } = fakeTimer();
    const asked: { range: TimeRange; points: number; resolve: (d: RangeData) => void }[] = [];
    const answered: RangeData[] = [];
    const recording = new PlotRecording(
      {
        fetchRange: (range, points) => new Promise<RangeData>((resolve) => asked.push({ range, points, resolve })),
        timer,
        debounce_ms: 150,
      },
      { answered: (d) => answered.push(d), failed: () => undefined, refreshDue: () => undefined },
    );
    recording.request({ from: T0 - 60_000, to: T0 }, 400, false);
    expect(asked).toHaveLength(0);
    expect(due.map((d) => d.delay_ms)).toEqual([150]);
    due.splice(0).forEach((d) => d.cb());
    expect(asked.map((a) => [a.range, a.points])).toEqual([[{ from_s: (T0 - 60_000) / 1000, to_s: T0 / 1000 }, 400]]);
    recording.request({ from: T0 - 30_000, to: T0 }, 400, true);
    expect(asked).toHaveLength(2);
    recording.stopRequests();
    asked[1]!.resolve({ range: asked[1]!.range, answer: {} as HistoryAnswer, events: [] });
    await new Promise((r) => setTimeout(r, 0));
    expect(answered).toHaveLength(0);
  });

  it("one refresh pending at a time, told when due; cleared, never", () => {
    const { timer, due } = fakeTimer();
    let refreshes = 0;
    const recording = new PlotRecording(
      { fetchRange: () => new Promise<RangeData>(() => undefined), timer },
      { answered: () => undefined, failed: () => undefined, refreshDue: () => refreshes++ },
    );
    recording.scheduleRefresh(3_600_000, 800);
    recording.scheduleRefresh(3_600_000, 800);
    expect(due.map((d) => d.delay_ms)).toEqual([4500]);
    due.splice(0).forEach((d) => d.cb());
    expect(refreshes).toBe(1);
    recording.scheduleRefresh(900_000, 800);
    recording.clearRefresh();
    expect(due).toHaveLength(0);
  });
});

describe("the traces of a drawing", () => {
  const setup = () => {
    const channels = new ChannelMap([joints]);
    const ring = new SampleRing(32_768, channels.channelCount);
    const traces = tracesOf(joints);
    const plot: DrawnPlot = {
      spec: joints,
      traces,
      visible: traces.map((_, i) => i !== 1),
      readOnly: false,
      ring,
      ringChannels: traces.map((t) => channels.channelOf(t.fieldName, t.channel)),
    };
    for (let t = T0 - 60_000; t <= T0; t += 10) ring.push(t, [1, 2, 3, 4, 5, 6]);
    return plot;
  };
  const answerOf = (range: TimeRange, recordedTo_s: number): HistoryAnswer =>
    historyAnswerOf(range, { t: [range.from_s, (range.from_s + range.to_s) / 2], t_last: [recordedTo_s - 1, recordedTo_s] });

  it("before an answer: the ring's line per signal over the range, the picker's choice kept", () => {
    const plot = setup();
    const drawn = historyTraces(plot, null, { from: T0 - 30_000, to: T0 }, 100, 0);
    const traces = drawn.traces as { x: number[]; visible: boolean; showlegend: boolean }[];
    expect(traces).toHaveLength(6);
    expect(traces.map((t) => t.visible)).toEqual([true, false, true, true, true, true]);
    expect(traces.every((t) => t.showlegend === false)).toBe(true);
    expect(Math.min(...traces[0]!.x)).toBeGreaterThanOrEqual(T0 - 30_000);
    expect(drawn.points).toBe(traces[0]!.x.length);
    expect(drawn.points).toBeGreaterThan(0);
    expect(drawn.points).toBeLessThanOrEqual(2 * 100);
  });

  it("with an answer: its envelope per signal, the ring only after the newest recorded frame, shifted", () => {
    const plot = setup();
    const range = { from: T0 - 120_000, to: T0 };
    const range_s = { from_s: range.from / 1000, to_s: range.to / 1000 };
    const recordedTo_s = (T0 - 3000) / 1000;
    const shift = 3_600_000;
    const data: RangeData = { range: range_s, answer: answerOf(range_s, recordedTo_s), events: [] };
    const drawn = historyTraces(plot, data, range, 100, shift);
    const traces = drawn.traces as { x: number[]; y: (number | null)[]; visible: boolean; fill?: string }[];
    expect(traces).toHaveLength(6 * 3); // per signal: min, max, the ring's newest
    expect(traces[0]!.y).toEqual([10, 10]);
    expect(traces[1]!.fill).toBe("tonexty");
    expect(traces[3]!.visible).toBe(false); // the second signal's min
    const tail = traces[2]!;
    expect(Math.min(...tail.x)).toBeGreaterThan(recordedTo_s * 1000 - shift);
    expect(Math.max(...tail.x)).toBeLessThanOrEqual(T0 - shift);
    expect(drawn.points).toBe(traces[0]!.x.length + tail.x.length);
  });
});
