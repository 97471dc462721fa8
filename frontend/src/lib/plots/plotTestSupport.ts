/** Fakes shared by the plot tests: a recording Plotly backend and a plot over a fresh ring. */
import type { HistoryAnswer, TimeRange } from "./historyView";
import { LivePlot, type PlotBackend, type StaticPicture } from "./plotting";
import { ChannelMap, JOINT_PLOTS } from "./plots";
import { SampleRing } from "../stream/ringBuffer";

export type Call = { op: string; args: unknown[] };

type XAxisLayout = { xaxis?: { autorange?: boolean; range?: unknown[] } };

export interface FakeBackendOptions {
  /**
   * `react` behaves as Plotly's does for the x axis: an explicit range is what it shows
   * afterwards (`zoomedAxes`), an autoranged axis is no zoom.
   */
  readonly plotlyReact?: boolean;
}

/**
 * A Plotly stand-in that records every call. `zoom` is what `zoomedAxes` reports; `fireRelayout`
 * tells the plot's relayout listener, as Plotly does after a person's zoom or pan.
 */
export function fakeBackend(
  options: FakeBackendOptions = {},
): PlotBackend & { calls: Call[]; zoom: Record<string, unknown[]>; fireRelayout: () => void } {
  const calls: Call[] = [];
  const zoom: Record<string, unknown[]> = {};
  let listener: (() => void) | null = null;
  const rec = (op: string) => (...args: unknown[]) => {
    calls.push({ op, args });
  };
  return {
    calls,
    zoom,
    fireRelayout: () => listener?.(),
    zoomedAxes: () => zoom,
    onRelayout: (_el, l) => {
      listener = l;
    },
    newPlot: rec("newPlot"),
    react: (...args: unknown[]) => {
      calls.push({ op: "react", args });
      if (options.plotlyReact !== true) return;
      const x = (args[2] as XAxisLayout).xaxis;
      if (x?.autorange === false && x.range !== undefined) zoom.xaxis = [...x.range];
      else delete zoom.xaxis;
    },
    extendTraces: rec("extendTraces"),
    restyle: rec("restyle"),
    relayout: rec("relayout"),
    downloadPng: rec("downloadPng"),
    purge: rec("purge"),
  };
}

/**
 * A static picture that records what it is asked (`drawn`); each drawing reports `range` as the
 * x range it drew.
 */
export function recordingPicture(range: readonly [number, number] = [0, 1]): { picture: StaticPicture; drawn: string[] } {
  const drawn: string[] = [];
  const picture: StaticPicture = {
    reset: () => drawn.push("reset"),
    extend: () => drawn.push("extend"),
    draw: () => {
      drawn.push("draw");
      return range;
    },
    show: (on) => drawn.push(on ? "show" : "hide"),
    savePng: (name) => drawn.push(`png ${name}`),
  };
  return { picture, drawn };
}

export function fakeElement(): HTMLElement {
  return { dataset: {} } as unknown as HTMLElement;
}

export const spec = JOINT_PLOTS[0]!;

export function setupPlot() {
  const channels = new ChannelMap([spec]);
  const ring = new SampleRing(4096, channels.channelCount);
  const backend = fakeBackend();
  const plot = new LivePlot(spec, ring, channels, backend, { window_ms: 10_000, theme: "light", readOnly: false });
  const el = fakeElement();
  plot.mount(el);
  const push = (t_ms: number) => ring.push(t_ms, [1, 2, 3, 4, 5, 6]);
  return { ring, backend, plot, el, push };
}

/** The recording's answer for J1…J6 positions over `range`, changed by `over`. */
export function historyAnswerOf(range: TimeRange, over: Partial<HistoryAnswer> = {}): HistoryAnswer {
  // Two buckets of every element: values 10…15 (min) and 20…25 (max).
  const t = [range.from_s, range.from_s + (range.to_s - range.from_s) / 2];
  return {
    robot: "left",
    from: range.from_s,
    to: range.to_s,
    points: 2,
    mode: "buckets",
    bucket_s: (range.to_s - range.from_s) / 2,
    frames: 1000,
    t,
    t_last: [t[1]! - 0.01, range.to_s - 0.01],
    series: [0, 1, 2, 3, 4, 5].map((i) => ({
      element: `joint_position.${i}`,
      field: "joint_position",
      label: `J${i + 1}`,
      unit: "degree",
      min: [10 + i, 10 + i],
      max: [20 + i, 20 + i],
      first: [],
      last: [],
    })),
    recording: true,
    ...over,
  };
}
