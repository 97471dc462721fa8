/**
 * The panel's custom plots: a signal picker (robot, numeric field) puts any numeric field of any
 * robot into a plot of its own, with the same controls as the fixed plots (window, pause, back
 * to live, channels, PNG). Each custom plot has its own stream of its robot at a reduced rate
 * and shares the page's plot coordinator. Nothing here writes.
 */
import { memo, useEffect, useMemo, useState } from "react";
import { CUSTOM_PLOT_RATE_HZ, customPlot, PICKABLE_FIELDS, refuseNewPlot, type CustomPlot } from "../lib/plots/customPlots";
import type { PlotCoordinator } from "../lib/plots/plotCoordinator";
import { createLiveRuntime } from "../lib/stream/runtime";
import { LivePlotView } from "./LivePlotView";
import { RuntimeContext } from "./runtimeContext";
import { useTheme } from "./theme";
import "../styles/customPlots.css";

function CustomPlotPane({ plot, coordinator, onRemove }: { plot: CustomPlot; coordinator: PlotCoordinator; onRemove: () => void }) {
  const theme = useTheme();
  const runtime = useMemo(
    () => createLiveRuntime([plot.spec], { robot: plot.robot, rate_hz: CUSTOM_PLOT_RATE_HZ, coordinator }),
    [plot, coordinator],
  );
  useEffect(() => {
    runtime.start();
    return () => runtime.stop();
  }, [runtime]);
  return (
    <div className="custom-plot" data-testid={`${plot.spec.id}-pane`} data-robot={plot.robot} data-field={plot.field}>
      <RuntimeContext.Provider value={runtime}>
        <LivePlotView spec={plot.spec} theme={theme} />
      </RuntimeContext.Provider>
      <button type="button" className="custom-plot__remove" data-testid={`${plot.spec.id}-remove`} onClick={onRemove}>
        Remove plot
      </button>
    </div>
  );
}

interface Props {
  /** The robot the panel shows (the picker's first choice). */
  readonly robot: string;
  /** Every robot of the service. */
  readonly robots: readonly string[];
  readonly coordinator: PlotCoordinator;
}

/** Memoised: the panel re-renders on each snapshot; the custom plots when their props change. */
export const CustomPlots = memo(function CustomPlots({ robot, robots, coordinator }: Props) {
  const [plots, setPlots] = useState<readonly CustomPlot[]>([]);
  const [pickedRobot, setPickedRobot] = useState(robot);
  const [pickedField, setPickedField] = useState<string>("");
  const [serial, setSerial] = useState(1);
  const choices = robots.includes(robot) ? robots : [robot, ...robots];
  const refusal = refuseNewPlot(plots, pickedRobot, pickedField);

  const add = () => {
    if (refusal !== null || !PICKABLE_FIELDS.some((f) => f.name === pickedField)) return;
    setPlots((p) => [...p, customPlot(pickedRobot, pickedField as CustomPlot["field"], serial)]);
    setSerial((n) => n + 1);
  };

  return (
    <div className="custom-plots">
      <div className="signal-picker" role="group" aria-label="Signal picker">
        <label>
          Robot{" "}
          <select data-testid="picker-robot" value={pickedRobot} onChange={(e) => setPickedRobot(e.target.value)}>
            {choices.map((name) => (
              <option key={name} value={name}>
                {name}
              </option>
            ))}
          </select>
        </label>
        <label>
          Signal{" "}
          <select data-testid="picker-field" value={pickedField} onChange={(e) => setPickedField(e.target.value)}>
            <option value="">choose…</option>
            {PICKABLE_FIELDS.map((f) => (
              <option key={f.name} value={f.name}>
                {f.description}
                {f.unit !== "" ? ` [${f.unit}]` : ""}
              </option>
            ))}
          </select>
        </label>
        <button type="button" data-testid="picker-add" onClick={add} disabled={refusal !== null}>
          Plot it
        </button>
        {refusal !== null && pickedField !== "" && (
          <span className="hint" data-testid="picker-refusal">
            {refusal}
          </span>
        )}
      </div>
      <div className="plot-grid">
        {plots.map((plot) => (
          <CustomPlotPane
            key={plot.spec.id}
            plot={plot}
            coordinator={coordinator}
            onRemove={() => setPlots((p) => p.filter((q) => q !== plot))}
          />
        ))}
      </div>
    </div>
  );
});
