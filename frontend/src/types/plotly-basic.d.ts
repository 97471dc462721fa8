// Minimal types for the parts of Plotly's partial "basic" bundle this app uses (through
// src/lib/plots/plotlyAdapter.ts only). The bundle ships no types of its own.
declare module "plotly.js-basic-dist-min" {
  type Datum = number | string | null;
  type PlotData = Record<string, unknown>;
  type PlotLayout = Record<string, unknown>;
  type PlotConfig = Record<string, unknown>;
  interface PlotlyStatic {
    newPlot(el: HTMLElement, data: PlotData[], layout?: PlotLayout, config?: PlotConfig): Promise<HTMLElement>;
    react(el: HTMLElement, data: PlotData[], layout?: PlotLayout, config?: PlotConfig): Promise<HTMLElement>;
    extendTraces(
      el: HTMLElement,
      update: { x: Datum[][]; y: Datum[][] },
      indices: number[],
      maxPoints?: number,
    ): Promise<HTMLElement>;
    restyle(el: HTMLElement, update: Record<string, unknown>, indices?: number[]): Promise<HTMLElement>;
    relayout(el: HTMLElement, update: Record<string, unknown>): Promise<HTMLElement>;
    purge(el: HTMLElement): void;
    downloadImage(
      el: HTMLElement,
      options: { format: "png" | "svg" | "jpeg" | "webp"; filename: string; width?: number; height?: number },
    ): Promise<string>;
    Plots: { resize(el: HTMLElement): Promise<void> };
  }
  const Plotly: PlotlyStatic;
  export default Plotly;
}
