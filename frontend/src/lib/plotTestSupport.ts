/** Fakes shared by the plot tests: a recording Plotly backend and a plot over a fresh ring. */
import { LivePlot, type PlotBackend } from "./plotting";
import { ChannelMap, JOINT_PLOTS } from "./plots";
import { SampleRing } from "./ringBuffer";

type Call = { op: string; args: unknown[] };

export function fakeBackend(): PlotBackend & { calls: Call[]; zoom: Record<string, unknown[]> } {
  const calls: Call[] = [];
  const zoom: Record<string, unknown[]> = {};
  const rec = (op: string) => (...args: unknown[]) => {
    calls.push({ op, args });
  };
  return {
    calls,
    zoom,
    zoomedAxes: () => zoom,
    newPlot: rec("newPlot"),
    react: rec("react"),
    extendTraces: rec("extendTraces"),
    restyle: rec("restyle"),
    relayout: rec("relayout"),
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
