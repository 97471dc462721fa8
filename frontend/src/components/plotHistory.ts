/**
 * Layer: React glue for the plots' way into the recording (no REST import here: the kiosk's
 * plots share LivePlotView and must not reach the REST client). The panel provides how a plot
 * fetches a robot's recorded fields (lib/history/historyApi.ts over the REST client) and the panel's
 * one time axis and cursor (lib/plots/timeRange.ts); without a provider (the kiosk) plots show the ring only.
 */
import { createContext, useContext } from "react";
import type { FetchRange } from "../lib/plots/historyView";
import type { PlotTimeRange } from "../lib/plots/timeRange";

export interface PlotHistoryAccess {
  /** How a plot of `robot` showing `fields` (the history API's parameter) fetches a range. */
  fetcher(robot: string, fields: string): FetchRange;
  /** The panel's one time axis and cursor: a move on one linked plot moves every linked plot. */
  readonly timeRange: PlotTimeRange;
}

export const PlotHistoryContext = createContext<PlotHistoryAccess | null>(null);

export function usePlotHistory(): PlotHistoryAccess | null {
  return useContext(PlotHistoryContext);
}
