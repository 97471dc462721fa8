// A live plot's way into the recording (lib/plots/plotting.ts with lib/plots/historyView.ts and
// lib/plots/timeRange.ts): a live window never fetches; a zoom or pan past the ring fetches its range
// (debounced, a stale answer dropped) and draws it merged with the ring's newest samples; a long
// window moves with now, refreshed from the recording; a marker's jump moves every linked plot; back
// to live; a range on screen costs nothing per frame.
import { describe, expect, it } from "vitest";
import type { HistoryAnswer, HistoryEvent, RangeData, TimeRange } from "./historyView";
import { LivePlot, type PlotBackend } from "./plotting";
import { MOVING_REFRESH_MIN_MS, type HistoryShown } from "./plotRecordingView";
import { ChannelMap, JOINT_PLOTS } from "./plots";
import { SampleRing } from "../stream/ringBuffer";
import { rangeOfMarker } from "./historyView";
import { PlotTimeRange, linkPlot } from "./timeRange";
import { fakeBackend, historyAnswerOf as answerOf } from "./plotTestSupport";
import { fakeTimer } from "./timerTestSupport";

type Trace = { name?: string; x: number[]; y: (number | null)[]; visible?: boolean; fill?: string };
type Layout = {
  uirevision: string;
  xaxis: { autorange: boolean; range?: number[]; uirevision?: string };
  yaxis: { autorange: boolean; uirevision?: string };
  shapes?: { x0: number }[];
};

const T0 = 1_795_500_000_000; // ms since the epoch
const spec = JOINT_PLOTS[0]!;

function setup(window_ms = 10_000, withHistory = true) {
  const backend = fakeBackend({ plotlyReact: true });
  const { calls, zoom } = backend;
  const fetches: { range: TimeRange; points: number; signal: AbortSignal; resolve: (d: RangeData) => void }[] = [];
  const { timer, fire, due } = fakeTimer();
  const channels = new ChannelMap([spec]);
  const ring = new SampleRing(32_768, channels.channelCount);
  const plot = new LivePlot(spec, ring, channels, backend, {
    window_ms,
    theme: "light",
    readOnly: false,
    ...(withHistory
      ? {
          history: {
            fetchRange: (range: TimeRange, points: number, signal: AbortSignal) =>
              new Promise<RangeData>((resolve) => fetches.push({ range, points, signal, resolve })),
            timer,
            debounce_ms: 200,
            now_ms: () => ring.newestTime() ?? T0,
          },
        }
      : {}),
  });
  const el = { dataset: {}, clientWidth: 880 } as unknown as HTMLElement;
  const shown: HistoryShown[] = [];
  plot.onHistory = (s) => shown.push(s);
  plot.mount(el);
  const push = (t_ms: number, v = 1) => ring.push(t_ms, [v, v, v, v, v, v]);
  const tz = new Date().getTimezoneOffset() * 60_000;
  /** A person zooms or pans the x axis to [from, to] (epoch ms): Plotly tells its listeners. */
  const moveTo = (from_ms: number, to_ms: number) => {
    zoom.xaxis = [from_ms - tz, to_ms - tz];
    backend.fireRelayout();
  };
  const autoscale = () => {
    delete zoom.xaxis;
    backend.fireRelayout();
  };
  const reacts = () => calls.filter((c) => c.op === "react");
  const lastReact = () => reacts().at(-1)!;
  const settle = () => new Promise((r) => setTimeout(r, 0));
  /** Answer fetch `i` with buckets over its range (and `events`). */
  const answer = async (i: number, over: Partial<HistoryAnswer> = {}, events: HistoryEvent[] = []) => {
    const f = fetches[i]!;
    f.resolve({ range: f.range, answer: answerOf(f.range, over), events });
    await settle();
  };
  let drawings = 0;
  /**
   * A person pans into the past to [from, to] (epoch ms; by default 5 to 3 min back), the view
   * settles, the fetch is answered (with `over`) and the plot draws it.
   */
  const showPast = async (from_ms = T0 - 300_000, to_ms = T0 - 200_000, over: Partial<HistoryAnswer> = {}) => {
    moveTo(from_ms, to_ms);
    fire();
    await answer(fetches.length - 1, over);
    plot.update(++drawings);
  };
  return { plot, el, ring, push, moveTo, autoscale, fetches, fire, due, calls, reacts, lastReact, answer, showPast, shown, tz, settle };
}

/** 60 s of frames at 100 Hz ending at T0. */
function fill(push: (t: number, v?: number) => void) {
  for (let t = T0 - 60_000; t <= T0; t += 10) push(t);
}

describe("a plot on its live window", () => {
  it("never fetches: not while streaming, not for a zoom inside what it holds", () => {
    const { plot, push, moveTo, fetches, fire, calls, el } = setup();
    fill(push);
    plot.update(0);
    for (let k = 1; k <= 20; k++) {
      push(T0 + k * 10);
      plot.update(k);
    }
    plot.setPointerInside(true);
    moveTo(T0 - 6000, T0 - 2000); // inside the 10 s window
    fire();
    expect(fetches).toHaveLength(0);
    expect(plot.viewKind).toBe("ring");
    expect(plot.isZoomed).toBe(true);
    expect(el.dataset.view).toBe("ring");
    expect(calls.some((c) => c.op === "extendTraces")).toBe(true);
  });
});

describe("a zoom or pan past the ring", () => {
  it("fetches its range once the view settles, about a point per pixel, and draws it", async () => {
    const { plot, push, moveTo, fetches, fire, due, lastReact, answer, el, tz } = setup();
    fill(push);
    plot.update(0);
    // Zoomed out: the view now starts 5 min back, before the 10 s the plot holds.
    moveTo(T0 - 300_000, T0);
    moveTo(T0 - 310_000, T0 - 10_000); // and panned on while still settling
    expect(plot.viewKind).toBe("fixed");
    expect(plot.isZoomed).toBe(true);
    expect(fetches).toHaveLength(0); // debounced
    expect(due[0]!.delay_ms).toBe(200);
    fire();
    expect(fetches).toHaveLength(1);
    expect(fetches[0]!.range).toEqual({ from_s: (T0 - 310_000) / 1000, to_s: (T0 - 10_000) / 1000 });
    expect(fetches[0]!.points).toBe(880 - 64 - 16); // the plotting area's width in px
    expect(plot.hasWork()).toBe(false); // nothing to draw before the answer
    await answer(0);
    expect(plot.hasWork()).toBe(true);
    expect(plot.update(1)).toBe(true);
    const traces = lastReact().args[1] as Trace[];
    // Per signal: min, max (the band filled), the ring's newest samples.
    expect(traces).toHaveLength(6 * 3);
    expect(traces[0]!.y).toEqual([10, 10]);
    expect(traces[1]!.y).toEqual([20, 20]);
    expect(traces[1]!.fill).toBe("tonexty");
    const layout = lastReact().args[2] as Layout;
    expect(layout.xaxis.autorange).toBe(false);
    expect(layout.xaxis.range).toEqual([T0 - 310_000 - tz, T0 - 10_000 - tz]);
    expect(el.dataset.view).toBe("fixed");
    expect(Number(el.dataset.frames)).toBe(1000);
    expect(Number(el.dataset.from)).toBe((T0 - 310_000) / 1000);
  });

  it("a new range fits its y axis to its data (Plotly's zoom-out widened it too), the drag mode kept", async () => {
    const { plot, push, showPast, lastReact, calls } = setup();
    fill(push);
    plot.update(0);
    await showPast();
    const first = lastReact().args[2] as Layout;
    await showPast(T0 - 400_000, T0 - 300_000); // the person pans on
    const drawn = lastReact().args[2] as Layout;
    expect(drawn.yaxis.uirevision).not.toBe(first.yaxis.uirevision); // the person's y zoom is not carried over
    expect(drawn.yaxis.autorange).toBe(true);
    expect(drawn.xaxis.uirevision).toBe(first.xaxis.uirevision); // x is where the person put it
    expect(drawn.uirevision).toBe(first.uirevision); // so is the drag mode (a pan goes on panning)
    // A jump elsewhere: a new x revision, so Plotly takes the range.
    plot.showRange({ from_s: (T0 - 900_000) / 1000, to_s: (T0 - 840_000) / 1000 });
    plot.update(3);
    expect((lastReact().args[2] as Layout).xaxis.uirevision).not.toBe(drawn.xaxis.uirevision);
    // Redrawn without a new answer (a signal hidden): the same y revision, a y zoom kept.
    const jumped = lastReact().args[2] as Layout;
    plot.setTraceVisible(2, false);
    plot.update(4);
    expect((lastReact().args[2] as Layout).yaxis.uirevision).toBe(jumped.yaxis.uirevision);
    expect((lastReact().args[1] as Trace[]).filter((t) => t.visible === false)).toHaveLength(3);
    expect(calls.some((c) => c.op === "restyle")).toBe(false);
  });

  it("costs nothing per frame while the range is on screen; our own drawing is no move", async () => {
    const { plot, push, moveTo, fetches, fire, showPast, calls } = setup();
    fill(push);
    plot.update(0);
    await showPast();
    const n = calls.length;
    for (let k = 1; k <= 100; k++) push(T0 + k * 10);
    expect(plot.hasWork()).toBe(false);
    expect(plot.update(2)).toBe(false);
    expect(calls).toHaveLength(n);
    // Plotly's relayout after our drawing shows the range we drew: no new request.
    moveTo(T0 - 300_000, T0 - 200_000);
    fire();
    expect(fetches).toHaveLength(1);
  });

  it("keeps fetching as the person pans on; an answer overtaken by a newer request is dropped", async () => {
    const { plot, push, moveTo, fetches, fire, answer, lastReact, reacts } = setup();
    fill(push);
    plot.update(0);
    moveTo(T0 - 300_000, T0 - 200_000);
    fire();
    moveTo(T0 - 400_000, T0 - 300_000);
    fire();
    expect(fetches).toHaveLength(2);
    expect(fetches[0]!.signal.aborted).toBe(true);
    const before = reacts().length;
    await answer(0); // late, for the old range
    expect(plot.hasWork()).toBe(false);
    await answer(1);
    plot.update(1);
    expect(reacts()).toHaveLength(before + 1);
    const from = (lastReact().args[2] as Layout).xaxis.range![0]!;
    expect(from + new Date().getTimezoneOffset() * 60_000).toBe(T0 - 400_000);
  });

  it("merges: the ring draws only what the recording has not written yet", async () => {
    const { plot, push, showPast, lastReact, fetches, tz } = setup();
    fill(push);
    plot.update(0);
    // The recording ends 3 s before the newest frame (the recorder's last flush).
    const recordedTo_s = (T0 - 3000) / 1000;
    await showPast(T0 - 120_000, T0, { t_last: [recordedTo_s - 60, recordedTo_s] });
    const traces = lastReact().args[1] as Trace[];
    const tail = traces[2]!;
    expect(tail.x.length).toBeGreaterThan(0);
    expect(Math.min(...tail.x)).toBeGreaterThan(recordedTo_s * 1000 - tz);
    expect(Math.max(...tail.x)).toBeLessThanOrEqual(T0 - tz);
    // No recording at all (recorder off): the ring draws all it holds of the range.
    await showPast(T0 - 120_000, T0 - 1000, { frames: 0, t: [], t_last: [], series: [] });
    const alone = lastReact().args[1] as Trace[];
    expect(alone).toHaveLength(6); // each signal: its line from the ring only
    expect(Math.min(...alone[0]!.x)).toBeLessThan(T0 - 59_000 - tz);
    expect(fetches).toHaveLength(2);
  });

  it("an error is told, and the plot stays up", async () => {
    const { plot, push, moveTo, fire, fetches, shown } = setup();
    fill(push);
    moveTo(T0 - 300_000, T0 - 200_000);
    fire();
    const f = fetches[0]!;
    // The loader reports the failure of the newest request only.
    (f as unknown as { resolve: (d: unknown) => void }).resolve(Promise.reject(new Error("HTTP 422: to")));
    await new Promise((r) => setTimeout(r, 0));
    expect(shown.at(-1)!.error).toBe("HTTP 422: to");
    expect(plot.viewKind).toBe("fixed");
  });
});

describe("long windows from the recording", () => {
  it("a 15 min window moves with now: fetched at once, then again as a bucket fills", async () => {
    const { plot, push, fetches, due, fire, answer, lastReact, el } = setup();
    fill(push);
    plot.update(0);
    plot.setWindow(15 * 60_000);
    expect(plot.viewKind).toBe("moving");
    expect(plot.isZoomed).toBe(false);
    expect(fetches).toHaveLength(1);
    expect(fetches[0]!.range).toEqual({ from_s: (T0 - 900_000) / 1000, to_s: T0 / 1000 });
    await answer(0);
    plot.update(1);
    expect(el.dataset.view).toBe("moving");
    expect((lastReact().args[1] as Trace[]).length).toBe(18);
    // The next request waits for about a bucket (900 s / 800 px ≈ 1.1 s; at least 2 s).
    expect(due.map((d) => d.delay_ms)).toEqual([MOVING_REFRESH_MIN_MS]);
    for (let k = 1; k <= 300; k++) push(T0 + k * 10); // 3 s more frames
    expect(plot.hasWork()).toBe(false); // not per frame
    fire();
    expect(fetches).toHaveLength(2);
    expect(fetches[1]!.range.to_s).toBe((T0 + 3000) / 1000);
    // Out of view: no requests, only the next turn.
    plot.onScreen = false;
    await answer(1);
    fire();
    expect(fetches).toHaveLength(2);
    expect(due).toHaveLength(1);
    plot.onScreen = true;
    fire();
    expect(fetches).toHaveLength(3);
    // Paused: frozen, no more requests.
    await answer(2);
    plot.update(2);
    plot.setPaused(true);
    fire();
    expect(fetches).toHaveLength(3);
    // Back to live asks again at once.
    plot.backToLive();
    expect(fetches).toHaveLength(4);
  });

  it("a zoom into a long window leaves it for a fixed range", () => {
    const { plot, push, fetches, fire, moveTo } = setup();
    fill(push);
    plot.setWindow(3_600_000);
    moveTo(T0 - 1_800_000, T0 - 1_700_000);
    fire();
    expect(plot.viewKind).toBe("fixed");
    expect(fetches.at(-1)!.range).toEqual({ from_s: (T0 - 1_800_000) / 1000, to_s: (T0 - 1_700_000) / 1000 });
  });
});

describe("markers and the shared time range", () => {
  const estop = (time_s: number) =>
    ({ kind: "robot_state", time: time_s, id: 7, robot: "left", from: 1, from_name: "STANDALONE_RUNNING", to: 0, to_name: "EMERGENCY_STOP" }) as HistoryEvent;

  it("a jump moves every linked plot to a minute around the moment, at once", async () => {
    const a = setup();
    const b = setup();
    fill(a.push);
    fill(b.push);
    a.plot.update(0);
    b.plot.update(0);
    const shared = new PlotTimeRange();
    // As each plot's view links it (plots/useLivePlot.ts).
    const unlinkA = linkPlot(shared, a.plot);
    linkPlot(shared, b.plot);
    const moment_s = (T0 - 240_000) / 1000;
    shared.jumpTo(rangeOfMarker({ time_s: moment_s, last_s: moment_s }));
    for (const p of [a, b]) {
      expect(p.plot.viewKind).toBe("fixed");
      expect(p.shown.at(-1)!.range).toEqual({ from_s: moment_s - 30, to_s: moment_s + 30 }); // told at once
      expect(p.fetches).toHaveLength(1); // no debounce for a jump
      expect(p.fetches[0]!.range).toEqual({ from_s: moment_s - 30, to_s: moment_s + 30 });
    }
    expect(shared.current).toEqual({ from_s: moment_s - 30, to_s: moment_s + 30 });
    // The answer's events become markers: dotted lines on the time axis, and told to the view.
    await a.answer(0, {}, [estop(moment_s)]);
    a.plot.update(1);
    const layout = a.lastReact().args[2] as Layout;
    expect(layout.shapes!.map((s) => s.x0)).toEqual([moment_s * 1000 - a.tz]);
    expect(a.shown.at(-1)!.events).toHaveLength(1);
    expect(a.shown.at(-1)!.range).toEqual({ from_s: moment_s - 30, to_s: moment_s + 30 });
    // An unlinked plot stays where it is.
    unlinkA();
    shared.jumpTo(rangeOfMarker({ time_s: moment_s + 100, last_s: moment_s + 100 }));
    expect(a.fetches).toHaveLength(1);
    expect(b.fetches).toHaveLength(2);
    expect(shared.listenerCount).toBe(1);
  });

  it("back to live on one linked plot brings back every linked plot; an unlinked one keeps its range", () => {
    const [a, b, c] = [setup(), setup(), setup()];
    const shared = new PlotTimeRange();
    const unlink = [a, b, c].map((p) => {
      fill(p.push);
      p.plot.update(0);
      return linkPlot(shared, p.plot);
    });
    shared.jumpTo({ from_s: (T0 - 270_000) / 1000, to_s: (T0 - 210_000) / 1000 });
    expect([a, b, c].map((p) => p.plot.viewKind)).toEqual(["fixed", "fixed", "fixed"]);
    unlink[2]!(); // c unlinked: its own range from now on
    a.plot.backToLive();
    expect([a, b, c].map((p) => p.plot.viewKind)).toEqual(["ring", "ring", "fixed"]);
  });

  it("a paused plot leaves its pause for a jump", () => {
    const { plot, push } = setup();
    fill(push);
    plot.update(0);
    plot.setPaused(true);
    plot.showRange({ from_s: T0 / 1000 - 100, to_s: T0 / 1000 - 40 });
    expect(plot.isPaused).toBe(false);
    expect(plot.viewKind).toBe("fixed");
  });
});

describe("back to live from the recording", () => {
  it("returns to the ring window; an answer still on its way is never drawn", async () => {
    const { plot, push, moveTo, fire, fetches, answer, lastReact, el, reacts } = setup();
    fill(push);
    plot.update(0);
    moveTo(T0 - 300_000, T0 - 200_000);
    fire();
    plot.backToLive();
    expect(fetches[0]!.signal.aborted).toBe(true);
    expect(plot.viewKind).toBe("ring");
    expect(plot.isZoomed).toBe(false);
    expect(el.dataset.view).toBe("ring");
    const live = lastReact().args[2] as Layout;
    expect(live.xaxis.autorange).toBe(true);
    const n = reacts().length;
    await answer(0);
    expect(plot.hasWork()).toBe(false);
    expect(reacts()).toHaveLength(n);
    push(T0 + 1000);
    expect(plot.hasWork()).toBe(true);
  });

  it("an autoscale (double click) on a range of the past is back to live too", async () => {
    const { plot, push, moveTo, fire, autoscale, fetches } = setup();
    fill(push);
    plot.update(0);
    moveTo(T0 - 300_000, T0 - 200_000);
    fire();
    autoscale();
    expect(plot.viewKind).toBe("ring");
    expect(fetches).toHaveLength(1);
  });

  it("the visible range: the range drawn, the zoom, or the moving window", async () => {
    const { plot, push, moveTo, showPast } = setup();
    fill(push);
    plot.update(0);
    expect(plot.visibleRange()).toEqual({ from_s: (T0 - 10_000) / 1000, to_s: T0 / 1000 });
    moveTo(T0 - 6000, T0 - 2000);
    expect(plot.visibleRange()).toEqual({ from_s: (T0 - 6000) / 1000, to_s: (T0 - 2000) / 1000 });
    await showPast();
    expect(plot.visibleRange()).toEqual({ from_s: (T0 - 300_000) / 1000, to_s: (T0 - 200_000) / 1000 });
  });
});

describe("a plot without the recording (the kiosk)", () => {
  it("keeps long windows out and never leaves the ring", () => {
    const channels = new ChannelMap([spec]);
    const ring = new SampleRing(1024, channels.channelCount);
    const noop = () => undefined;
    const backend: PlotBackend = {
      newPlot: noop,
      react: noop,
      extendTraces: noop,
      restyle: noop,
      relayout: noop,
      purge: noop,
      zoomedAxes: () => ({ xaxis: [0, 1] }),
    };
    const plot = new LivePlot(spec, ring, channels, backend, { window_ms: 10_000, theme: "dark", readOnly: true });
    plot.mount({ dataset: {} } as unknown as HTMLElement);
    expect(plot.reachesHistory).toBe(false);
    plot.setWindow(3_600_000);
    expect(plot.viewKind).toBe("ring");
    plot.showRange({ from_s: 1, to_s: 2 });
    expect(plot.viewKind).toBe("ring");
  });
});

describe("steps from the plot's buttons and keys (the same decision as a person's zoom or pan)", () => {
  const xRange = (layout: Layout) => layout.xaxis.range;

  it("zoom in and pan inside the ring stay a ring zoom; a pan past it goes into the recording", async () => {
    const { plot, push, fetches, fire, due, lastReact, el, tz, answer } = setup();
    fill(push);
    plot.update(0);
    plot.step("zoomIn"); // 10 s → 5 s around the centre, drawn at once
    expect(plot.viewKind).toBe("ring");
    expect(plot.isZoomed).toBe(true);
    expect(el.dataset.zoomed).toBe("true");
    expect(xRange(lastReact().args[2] as Layout)).toEqual([T0 - 7500 - tz, T0 - 2500 - tz]);
    plot.step("earlier"); // [T0 - 10 s, T0 - 5 s]: still what the ring view holds
    expect(plot.viewKind).toBe("ring");
    expect(xRange(lastReact().args[2] as Layout)).toEqual([T0 - 10_000 - tz, T0 - 5000 - tz]);
    fire();
    expect(fetches).toHaveLength(0);
    // Streaming on keeps the step's range (the zoom is carried, as a person's).
    push(T0 + 10);
    plot.update(1);
    plot.setPointerInside(true);
    expect(xRange(lastReact().args[2] as Layout)).toEqual([T0 - 10_000 - tz, T0 - 5000 - tz]);
    plot.step("earlier"); // [T0 - 12.5 s, T0 - 7.5 s]: before the ring view
    expect(plot.viewKind).toBe("fixed");
    expect(plot.hasWork()).toBe(true); // drawn at once with what is at hand, not after the answer
    plot.update(2);
    expect(el.dataset.view).toBe("fixed");
    expect(xRange(lastReact().args[2] as Layout)).toEqual([T0 - 12_500 - tz, T0 - 7500 - tz]);
    expect(due.at(-1)!.delay_ms).toBe(200); // debounced, like a person's moves
    fire();
    expect(fetches.map((f) => f.range)).toEqual([{ from_s: (T0 - 12_500) / 1000, to_s: (T0 - 7500) / 1000 }]);
    await answer(0);
    plot.update(3);
    expect(Number(el.dataset.frames)).toBe(1000);
  });

  it("while the ring holds less than the window, a zoom in of what it draws stays a ring zoom", () => {
    // Shortly after the page opened: 3 s of frames, drawn autoranged over those 3 s.
    const { plot, push, fetches, fire, lastReact, tz } = setup();
    for (let t = T0 - 3000; t <= T0; t += 10) push(t);
    plot.update(0);
    expect(plot.visibleRange()).toEqual({ from_s: (T0 - 3000) / 1000, to_s: T0 / 1000 });
    plot.step("zoomIn"); // the middle 1.5 s of the 3 s drawn, not of a 10 s window not yet filled
    expect(plot.viewKind).toBe("ring");
    expect(plot.isZoomed).toBe(true);
    expect(xRange(lastReact().args[2] as Layout)).toEqual([T0 - 2250 - tz, T0 - 750 - tz]);
    fire();
    // The one request is the window's start from the recording (lib/plots/plotBackfill.ts), asked at
    // the first drawing: the 7 s before the ring's oldest frame; the zoom asks nothing.
    expect(fetches.map((f) => f.range)).toEqual([{ from_s: (T0 - 10_000) / 1000, to_s: (T0 - 3000) / 1000 }]);
    // Before what the ring holds is the recording, as with a full ring.
    plot.step("earlier");
    plot.step("earlier");
    expect(plot.viewKind).toBe("fixed");
  });

  it("zoom out from live reaches the recording; steps before a drawing add to the view's own range", () => {
    const { plot, push, fetches, fire } = setup();
    fill(push);
    plot.update(0);
    plot.step("zoomOut"); // 20 s ending at now: before the 10 s the ring view holds
    expect(plot.viewKind).toBe("fixed");
    plot.step("zoomOut");
    plot.step("earlier");
    fire();
    // One request (debounced), for 40 s ending 20 s before now.
    expect(fetches.map((f) => f.range)).toEqual([{ from_s: (T0 - 60_000) / 1000, to_s: (T0 - 20_000) / 1000 }]);
  });

  it("later onto now is back to live; later while live does nothing more than that", () => {
    const { plot, push, fetches, fire, lastReact, el } = setup();
    fill(push);
    plot.update(0);
    plot.step("zoomOut");
    plot.step("earlier"); // [T0 - 30 s, T0 - 10 s]
    fire();
    expect(fetches).toHaveLength(1);
    plot.update(1);
    plot.step("later"); // [T0 - 20 s, T0]: at now
    expect(plot.viewKind).toBe("ring");
    expect(plot.isZoomed).toBe(false);
    expect(fetches[0]!.signal.aborted).toBe(true);
    expect((lastReact().args[2] as Layout).xaxis.autorange).toBe(true);
    expect(el.dataset.view).toBe("ring");
    plot.step("later");
    expect(plot.viewKind).toBe("ring");
    fire();
    expect(fetches).toHaveLength(1);
  });

  it("in a long moving window a step leaves it for a fixed range", () => {
    const { plot, push, fetches, fire } = setup();
    fill(push);
    plot.setWindow(3_600_000);
    fire();
    const n = fetches.length;
    plot.step("zoomIn"); // the hour's middle half hour
    expect(plot.viewKind).toBe("fixed");
    fire();
    expect(fetches).toHaveLength(n + 1);
    expect(fetches.at(-1)!.range).toEqual({ from_s: (T0 - 2_700_000) / 1000, to_s: (T0 - 900_000) / 1000 });
    plot.step("later");
    plot.step("later"); // onto now: the hour's moving window again
    expect(plot.viewKind).toBe("moving");
  });

  it("paused: a ring zoom moves Plotly's axis and adds no data; the keyboard's focus makes it interactive", () => {
    const { plot, push, calls, el, tz } = setup();
    fill(push);
    plot.update(0);
    expect(el.dataset.interactive).toBe("false");
    plot.setFocusInside(true);
    expect(el.dataset.interactive).toBe("true");
    const interactive = calls.at(-1)!;
    expect(interactive.op).toBe("react");
    expect((interactive.args[3] as { staticPlot?: boolean }).staticPlot).toBeUndefined();
    plot.setFocusInside(false);
    expect(el.dataset.interactive).toBe("false");
    plot.setPaused(true);
    push(T0 + 10);
    const n = calls.length;
    plot.step("zoomIn");
    expect(calls.slice(n).map((c) => c.op)).toEqual(["relayout"]);
    expect(calls.at(-1)!.args[1]).toEqual({ "xaxis.autorange": false, "xaxis.range": [T0 - 7500 - tz, T0 - 2500 - tz] });
    expect(plot.isZoomed).toBe(true);
    expect(plot.isPaused).toBe(true);
  });
});

describe("steps of a plot without the recording", () => {
  it("stay within what its ring view holds; zooming out to all of it is live again", () => {
    const { plot, push, lastReact, tz } = setup(10_000, false);
    fill(push);
    plot.update(0);
    expect(plot.reachesHistory).toBe(false);
    plot.step("zoomIn");
    expect(plot.isZoomed).toBe(true);
    plot.step("earlier");
    plot.step("earlier"); // clamped at the ring view's start
    expect((lastReact().args[2] as Layout).xaxis.range).toEqual([T0 - 10_000 - tz, T0 - 5000 - tz]);
    expect(plot.viewKind).toBe("ring");
    plot.step("zoomOut"); // 10 s from the ring view's start: all of it
    expect(plot.isZoomed).toBe(false);
    expect(plot.viewKind).toBe("ring");
  });

  it("a read-only plot (the kiosk) takes no steps", () => {
    const channels = new ChannelMap([spec]);
    const ring = new SampleRing(1024, channels.channelCount);
    const calls: string[] = [];
    const rec = (op: string) => () => void calls.push(op);
    const backend: PlotBackend = {
      newPlot: rec("newPlot"),
      react: rec("react"),
      extendTraces: rec("extendTraces"),
      restyle: rec("restyle"),
      relayout: rec("relayout"),
      purge: rec("purge"),
      zoomedAxes: () => ({}),
    };
    const plot = new LivePlot(spec, ring, channels, backend, { window_ms: 10_000, theme: "dark", readOnly: true });
    plot.mount({ dataset: {} } as unknown as HTMLElement);
    for (let t = T0 - 20_000; t <= T0; t += 10) ring.push(t, [1, 2, 3, 4, 5, 6]);
    for (const s of ["zoomIn", "zoomOut", "earlier", "later"] as const) plot.step(s);
    expect(calls).toEqual(["newPlot"]);
    expect(plot.isZoomed).toBe(false);
  });
});
