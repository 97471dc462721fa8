/** I/O: input lamps, output toggles (command and actual), analog inputs and outputs. */
import type { Frame } from "../generated/layout";
import { AnalogInputs, LampRow } from "../components/IoView";
import { channelNumber, commandField } from "../lib/layout/layoutInfo";
import { AnalogOutputs } from "./AnalogOutputs";
import { OutputToggle } from "./OutputToggle";
import { useWrites } from "./writeContext";

function OutputRow({ field, testPrefix, frame }: { field: "controlbox_do" | "tool_do"; testPrefix: string; frame: Frame | null }) {
  const writes = useWrites();
  const info = commandField(field);
  return (
    <div className="toggle-row" role="group" aria-label={info.description}>
      {info.channels.map((label, i) => (
        <OutputToggle
          key={label}
          field={field}
          index={i}
          label={label}
          testId={`${testPrefix}-${channelNumber(label)}`}
          actual={frame === null ? null : (frame[field][i] ?? null)}
          command={writes.command?.image[field][i] ?? null}
          kind="output"
        />
      ))}
    </div>
  );
}

export function IoSection({ frame }: { readonly frame: Frame | null }) {
  return (
    <div className="io">
      <h3>ControlBox digital inputs</h3>
      <LampRow field="controlbox_di" testPrefix="di" frame={frame} />
      <h3>ControlBox digital outputs</h3>
      <OutputRow field="controlbox_do" testPrefix="do" frame={frame} />
      <h3>Tool digital inputs</h3>
      <LampRow field="tool_di" testPrefix="tool-di" frame={frame} />
      <h3>Tool digital outputs</h3>
      <OutputRow field="tool_do" testPrefix="tool-do" frame={frame} />
      <div className="io__analog">
        <div>
          <h3>Analog inputs</h3>
          <AnalogInputs frame={frame} />
        </div>
        <div>
          <h3>Analog outputs</h3>
          <AnalogOutputs frame={frame} />
        </div>
      </div>
    </div>
  );
}
