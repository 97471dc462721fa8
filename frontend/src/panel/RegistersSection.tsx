/** 64 bit input registers as toggles (the image sent), 64 bit output registers as lamps. */
import type { Frame } from "../generated/layout";
import { LampRow } from "../components/IoView";
import { channelNumber, commandField } from "../lib/layout/layoutInfo";
import { OutputToggle } from "./OutputToggle";
import { useWrites } from "./writeContext";

export function RegistersSection({ frame }: { readonly frame: Frame | null }) {
  const writes = useWrites();
  const info = commandField("bit_input_registers");
  const image = writes.command?.image.bit_input_registers ?? null;
  return (
    <div className="registers">
      <label className="setting">
        <input
          type="checkbox"
          data-testid="setting-confirm-registers"
          checked={writes.confirmRegisters}
          onChange={(e) => writes.setConfirmRegisters(e.target.checked)}
        />
        Ask for confirmation before writing a register
      </label>
      <div className="registers__grids">
        <div>
          <h3>Bit input registers (to the robot)</h3>
          <div className="register-grid" role="group" aria-label={info.description}>
            {info.channels.map((label, i) => {
              const n = channelNumber(label);
              // The robot does not report its bit input registers: their actual state is the
              // O→T image that went out, which the backend confirms (docs/api.md, Writing).
              const value = image === null ? null : (image[i] ?? null);
              return (
                <OutputToggle
                  key={label}
                  field="bit_input_registers"
                  index={i}
                  label={String(n)}
                  testId={`bit-in-${n}`}
                  actual={value}
                  command={value}
                  kind="register"
                  compact
                />
              );
            })}
          </div>
        </div>
        <div>
          <h3>Bit output registers (from the robot)</h3>
          <div className="register-grid">
            <LampRow field="bit_output_registers" testPrefix="bit-out" frame={frame} variant="register" numberOnly />
          </div>
        </div>
      </div>
    </div>
  );
}
