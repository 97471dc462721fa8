// The plots' way into the recording (lib/plots/historyView.ts): custom ranges, a marker's range,
// buckets from the width, envelopes with gaps, the newest frame of an answer, marker placement,
// export links, and the loader's debounce and cancelling of stale requests.
import { describe, expect, it } from "vitest";
import {
  RangeLoader,
  axisTimeToEpochS,
  bucketsForWidth,
  customRange,
  envelopeTraceSets,
  exportUrl,
  fieldsOf,
  MARKER_SPACING,
  markerSpacing,
  markersOf,
  newestRecorded,
  rangeOfMarker,
  type HistoryAnswer,
  type HistoryEvent,
  type RangeData,
  type TimeRange,
} from "./historyView";
import { JOINT_PLOTS, TCP_PLOTS } from "./plots";
import { fakeTimer } from "./timerTestSupport";

const NOW = 1_795_500_000;

describe("ranges", () => {
  it("custom ranges are checked; a marker of one event is in the middle of its range", () => {
    expect(customRange(NOW - 60, NOW)).toEqual({ from_s: NOW - 60, to_s: NOW });
    expect(customRange(NOW, NOW)).toMatch(/after the start/);
    expect(customRange(Number.NaN, NOW)).toMatch(/Both times/);
    expect(rangeOfMarker({ time_s: NOW, last_s: NOW })).toEqual({ from_s: NOW - 30, to_s: NOW + 30 });
    expect(rangeOfMarker({ time_s: NOW, last_s: NOW }, 5)).toEqual({ from_s: NOW - 5, to_s: NOW + 5 });
  });

  it("asks for one bucket per pixel, within the service's 1–5000", () => {
    expect(bucketsForWidth(812.4)).toBe(812);
    expect(bucketsForWidth(20_000)).toBe(5000);
    expect(bucketsForWidth(-5)).toBe(50);
    expect(bucketsForWidth(Number.NaN)).toBe(1000);
  });

  it("reads Plotly's date-axis values back as epoch seconds", () => {
    const shift_ms = -60 * 60_000; // UTC+1
    expect(axisTimeToEpochS(NOW * 1000 - shift_ms, shift_ms)).toBe(NOW);
    expect(axisTimeToEpochS("2026-11-24 07:00:00.5", 0)).toBe(Date.UTC(2026, 10, 24, 7, 0, 0, 500) / 1000);
    expect(axisTimeToEpochS("2026-11-24 08:00:00", shift_ms)).toBe(Date.UTC(2026, 10, 24, 7) / 1000);
    expect(axisTimeToEpochS(null, 0)).toBeNaN();
  });

  it("asks for a plot's fields", () => {
    expect(fieldsOf(JOINT_PLOTS[0]!)).toBe("joint_position");
    expect(fieldsOf(TCP_PLOTS.find((s) => s.id === "plot-external-force")!)).toBe("external_force,external_moment");
  });
});

function answer(over: Partial<HistoryAnswer>): HistoryAnswer {
  return {
    robot: "left",
    from: NOW,
    to: NOW + 40,
    points: 4,
    mode: "buckets",
    bucket_s: 10,
    frames: 3000,
    t: [],
    series: [],
    recording: true,
    ...over,
  };
}

describe("envelopes", () => {
  const spec = JOINT_PLOTS[0]!;
  it("draws each element as a min and a max line, the band filled, a missing bucket a gap", () => {
    const a = answer({
      t: [NOW, NOW + 10, NOW + 30],
      series: [
        { element: "joint_position.0", field: "joint_position", label: "J1", unit: "degree", min: [1, 2, 3], max: [4, 5, 6], first: [], last: [] },
      ],
    });
    const traces = envelopeTraceSets(a, spec, 0).flat() as { name: string; x: (number | null)[]; y: (number | null)[]; fill?: string; hovertemplate: string }[];
    expect(traces.map((t) => t.name)).toEqual(["J 1 min", "J 1 max"]);
    const [min, max] = traces;
    // The bucket at +20 s is missing: a null after +10 s breaks the line.
    expect(min!.y).toEqual([1, 2, null, 3]);
    expect(max!.y).toEqual([4, 5, null, 6]);
    expect(min!.x[0]).toBe(NOW * 1000);
    expect(min!.x[3]).toBe((NOW + 30) * 1000);
    expect(max!.fill).toBe("tonexty");
    expect(max!.hovertemplate).toContain("degree");
  });

  it("draws raw frames as one line per element, shifted to local time", () => {
    const a = answer({
      mode: "raw",
      bucket_s: null,
      t: [NOW, NOW + 0.01],
      series: [{ element: "joint_position.1", field: "joint_position", label: "J2", unit: "degree", values: [7, null] }],
    });
    const traces = envelopeTraceSets(a, spec, 3_600_000).flat() as { name: string; x: number[]; y: (number | null)[] }[];
    expect(traces).toHaveLength(1);
    expect(traces[0]!.name).toBe("J 2");
    expect(traces[0]!.x).toEqual([NOW * 1000 - 3_600_000, (NOW + 0.01) * 1000 - 3_600_000]);
    expect(traces[0]!.y).toEqual([7, null]);
  });

  it("groups the traces per signal of the plot (a signal without a series has none)", () => {
    const a = answer({
      t: [NOW],
      series: [{ element: "joint_position.2", field: "joint_position", label: "J3", unit: "degree", min: [1], max: [2], first: [], last: [] }],
    });
    const sets = envelopeTraceSets(a, spec, 0);
    expect(sets).toHaveLength(6);
    expect(sets.map((set) => set.length)).toEqual([0, 0, 2, 0, 0, 0]);
  });

  it("knows the newest frame an answer holds (the ring draws what comes after it)", () => {
    expect(newestRecorded(answer({ frames: 0 }))).toBeNull();
    expect(newestRecorded(answer({ t: [NOW, NOW + 10], t_last: [NOW + 9.99, NOW + 12.5], frames: 20 }))).toBe(NOW + 12.5);
    expect(newestRecorded(answer({ mode: "raw", t: [NOW, NOW + 0.01], frames: 2 }))).toBe(NOW + 0.01);
  });
});

describe("markers", () => {
  const range: TimeRange = { from_s: NOW, to_s: NOW + 100 };
  const estop = {
    kind: "robot_state",
    time: NOW + 25,
    id: 7,
    robot: "left",
    from: 1,
    from_name: "STANDALONE_RUNNING",
    to: 0,
    to_name: "EMERGENCY_STOP",
  } as HistoryEvent;
  it("places events on the time axis as a fraction of the range", () => {
    const markers = markersOf([estop], range);
    expect(markers).toHaveLength(1);
    expect(markers[0]!.at).toBeCloseTo(0.25);
    // In words, as the robot's pendant says it (issue 38): never "State EMERGENCY_STOP".
    expect(markers[0]!.label).toBe("Robot state Emergency stop");
    expect(markers[0]!.kind).toBe("alarm"); // an emergency stop is marked as urgent
    expect(markers[0]!.time_s).toBe(NOW + 25);
  });

  it("joins events too close to tell apart into one marker; zooming in separates them", () => {
    // Bins of 1.5 s over 100 s: 25 s and 25.4 s share the one from 24 s to 25.5 s.
    const standby = { ...estop, id: 8, time: NOW + 25.4, to_name: "STANDALONE_STANDBY" } as HistoryEvent;
    const later = { ...estop, id: 9, time: NOW + 40, to_name: "STANDALONE_RUNNING" } as HistoryEvent;
    const markers = markersOf([estop, standby, later], range);
    expect(markers.map((m) => m.label)).toEqual(["Robot state Emergency stop; Robot state Standalone standby", "Robot state Standalone running"]);
    expect(markers[0]!.time_s).toBe(NOW + 25);
    expect(markers[0]!.last_s).toBe(NOW + 25.4);
    // A click shows every event of the marker, half a minute either side.
    expect(rangeOfMarker(markers[0]!)).toEqual({ from_s: NOW - 5, to_s: NOW + 55.4 });
    expect(rangeOfMarker(markers[1]!)).toEqual({ from_s: NOW + 10, to_s: NOW + 70 });
    expect(markers[0]!.events).toHaveLength(2);
    expect(markers[1]!.kind).toBe("robot_state");
    const zoomed = markersOf([estop, standby, later], { from_s: NOW + 20, to_s: NOW + 30 });
    expect(zoomed).toHaveLength(2);
    expect(zoomed[0]!.at).toBeCloseTo(0.5, 6);
    expect(zoomed[1]!.at).toBeCloseTo(0.54, 6);
  });

  it("a marker's events do not depend on the events around it (an answer with more of them)", () => {
    // Events 8 s apart over 10 minutes, bins of 9 s: grouped by their neighbours, dropping the
    // first event would regroup every marker after it; in bins, each keeps its events.
    const wide: TimeRange = { from_s: NOW, to_s: NOW + 600 };
    const all = Array.from({ length: 70 }, (_, i) => ({ ...estop, id: i, time: NOW + 3 + 8 * i }) as HistoryEvent);
    const groups = (list: readonly HistoryEvent[]) =>
      new Map(markersOf(list, wide).map((m) => [m.time_s, m.events.map((e) => e.time_s).join()]));
    const full = groups(all);
    const later = groups(all.slice(21));
    for (const [time_s, events] of later) {
      if (time_s > NOW + 3 + 8 * 22) expect(full.get(time_s)).toBe(events);
    }
  });

  it("markers never overlap: one pushed right stays inside its bin", () => {
    // Events at the end of one bin and the start of the next are a spacing apart on screen.
    const a = { ...estop, id: 1, time: NOW + 2.9 } as HistoryEvent;
    const b = { ...estop, id: 2, time: NOW + 3.05 } as HistoryEvent;
    const markers = markersOf([a, b], range); // bins 1.5 s: 1.5–3 and 3–4.5
    expect(markers).toHaveLength(2);
    expect(markers[1]!.at - markers[0]!.at).toBeCloseTo(MARKER_SPACING, 9);
    expect(markers[1]!.at).toBeLessThan(4.5 / 100);
  });

  it("on a narrow plot, markers closer than a marker's width share one", () => {
    const soon = { ...estop, id: 8, time: NOW + 28, to_name: "STANDALONE_STANDBY" } as HistoryEvent;
    expect(markerSpacing(2000)).toBe(MARKER_SPACING);
    expect(markerSpacing(600)).toBe(30 / 600);
    expect(markerSpacing(0)).toBe(MARKER_SPACING);
    expect(markerSpacing(600, 48)).toBe(48 / 600); // touch: 44 px targets
    expect(markersOf([estop, soon], range)).toHaveLength(2); // 3 % apart
    expect(markersOf([estop, soon], range, markerSpacing(600))).toHaveLength(1); // 18 px apart
  });

  it("marks each cycle's start with its duration (the robot's cycle trigger)", () => {
    const cycle = {
      kind: "cycle",
      time: NOW + 50,
      end: NOW + 58.1,
      duration_s: 8.1,
      text: "Cycle of 8.10 s",
      robot: "left",
      id: 11,
    } as HistoryEvent;
    const markers = markersOf([cycle], range);
    expect(markers).toHaveLength(1);
    expect(markers[0]!.at).toBeCloseTo(0.5);
    expect(markers[0]!.label).toBe("Cycle 8.10 s");
    expect(markers[0]!.kind).toBe("cycle");
  });

  it("leaves out events outside the range and kinds that are no markers", () => {
    const before = { ...estop, time: NOW - 1 } as HistoryEvent;
    const atEnd = { ...estop, time: NOW + 100 } as HistoryEvent; // `to` is excluded
    const write = { kind: "write", time: NOW + 50 } as unknown as HistoryEvent;
    expect(markersOf([before, atEnd, write], range)).toEqual([]);
    expect(markersOf([estop], { from_s: NOW, to_s: NOW })).toEqual([]);
  });
});

describe("export", () => {
  it("links the range shown in each format, with the plot's fields", () => {
    const url = new URL(exportUrl("left arm", { from_s: NOW, to_s: NOW + 60.5 }, "csv", "joint_position"), "http://x");
    expect(url.pathname).toBe("/api/v1/robots/left%20arm/export");
    expect(url.searchParams.get("from")).toBe(`${NOW}.000`);
    expect(url.searchParams.get("to")).toBe(`${NOW + 60}.500`);
    expect(url.searchParams.get("format")).toBe("csv");
    expect(url.searchParams.get("fields")).toBe("joint_position");
    expect(new URL(exportUrl("left", { from_s: 1, to_s: 2 }, "mcap", null), "http://x").searchParams.has("fields")).toBe(false);
  });
});

describe("RangeLoader", () => {
  function deferredFetch() {
    const calls: { range: TimeRange; points: number; signal: AbortSignal; resolve: (d: RangeData) => void; reject: (e: Error) => void }[] = [];
    const fetchRange = (range: TimeRange, points: number, signal: AbortSignal) =>
      new Promise<RangeData>((resolve, reject) => calls.push({ range, points, signal, resolve, reject }));
    return { calls, fetchRange };
  }

  const data = (range: TimeRange): RangeData => ({ range, answer: answer({}), events: [] });

  it("debounces: only the last range of a burst is fetched", async () => {
    const { timer, fire } = fakeTimer();
    const { calls, fetchRange } = deferredFetch();
    const got: RangeData[] = [];
    const loader = new RangeLoader(fetchRange, (d) => got.push(d), () => undefined, 200, timer);
    for (let i = 0; i < 5; i++) loader.request({ from_s: i, to_s: i + 10 }, 800);
    expect(calls).toHaveLength(0);
    fire();
    expect(calls).toHaveLength(1);
    expect(calls[0]!.range).toEqual({ from_s: 4, to_s: 14 });
    expect(calls[0]!.points).toBe(800);
    calls[0]!.resolve(data(calls[0]!.range));
    await Promise.resolve();
    await Promise.resolve();
    expect(got.map((d) => d.range.from_s)).toEqual([4]);
  });

  it("a newer request aborts the one in flight, whose answer is never drawn", async () => {
    const { timer } = fakeTimer();
    const { calls, fetchRange } = deferredFetch();
    const got: RangeData[] = [];
    const errors: string[] = [];
    const loader = new RangeLoader(fetchRange, (d) => got.push(d), (e) => errors.push(e), 200, timer);
    loader.request({ from_s: 0, to_s: 10 }, 100, true);
    loader.request({ from_s: 5, to_s: 15 }, 100, true);
    expect(calls[0]!.signal.aborted).toBe(true);
    expect(calls[1]!.signal.aborted).toBe(false);
    calls[1]!.resolve(data(calls[1]!.range));
    calls[0]!.resolve(data(calls[0]!.range)); // late: dropped
    await new Promise((r) => setTimeout(r, 0));
    expect(got.map((d) => d.range.from_s)).toEqual([5]);
    loader.request({ from_s: 9, to_s: 19 }, 100, true);
    calls[2]!.reject(new Error("HTTP 422"));
    await new Promise((r) => setTimeout(r, 0));
    expect(errors).toEqual(["HTTP 422"]);
    loader.request({ from_s: 9, to_s: 19 }, 100, true);
    loader.stop();
    expect(calls[3]!.signal.aborted).toBe(true);
    calls[3]!.resolve(data(calls[3]!.range));
    await new Promise((r) => setTimeout(r, 0));
    expect(got).toHaveLength(1);
  });
});
