/** Fakes shared by the plot tests: a recording Plotly backend and a plot over a fresh ring. */
import { LivePlot, type PlotBackend } from "./plotting";
import { ChannelMap, JOINT_PLOTS } from "./plots";
import { SampleRing } from "./ringBuffer";

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
