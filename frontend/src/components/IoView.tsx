/** Read-only I/O views shared by the panel and the kiosk: input lamps and analog inputs. */
import type { Frame } from "../generated/layout";
import { analogTypeName, analogUnit, channelNumber, frameField } from "../lib/layout/layoutInfo";
import { tagLabel } from "../lib/alarms/alarms";
import { Lamp } from "./Lamp";
import { useTagNames } from "./tagNames";

type BoolField = "controlbox_di" | "controlbox_do" | "tool_di" | "tool_do" | "bit_output_registers";

interface LampRowProps {
  readonly field: BoolField;
  readonly testPrefix: string;
  readonly frame: Frame | null;
  readonly variant?: "io" | "register";
  /** Shorter labels for dense grids: the channel number only. */
  readonly numberOnly?: boolean;
}

/** One lamp per channel of a boolean frame field; test ids use the layout's channel numbers. */
export function LampRow({ field, testPrefix, frame, variant = "io", numberOnly = false }: LampRowProps) {
  const info = frameField(field);
  const values = frame?.[field] ?? null;
  const tags = useTagNames();
  return (
    <div className={`lamp-row lamp-row--${variant}`} role="group" aria-label={info.description}>
      {info.channels.map((label, i) => {
        const n = channelNumber(label);
        const tag = tags[`${field}.${i}`];
        return (
          <Lamp
            key={label}
            testId={`${testPrefix}-${n}`}
            label={numberOnly ? String(n) : label}
            tag={numberOnly ? undefined : tag}
            title={tagLabel(label, tag)}
            on={values === null ? null : (values[i] ?? null)}
            variant={variant}
          />
        );
      })}
    </div>
  );
}

export function formatAnalog(value: number | null | undefined): string {
  return value === null || value === undefined || !Number.isFinite(value) ? "—" : value.toFixed(3);
}

/** Analog inputs with their type and unit (both from the layout). */
export function AnalogInputs({ frame }: { readonly frame: Frame | null }) {
  const info = frameField("analog_input");
  const tags = useTagNames();
  const typeInfo = frameField("analog_input_type");
  return (
    <div className="analog-list">
      {info.channels.map((label, i) => {
        const type = frame?.analog_input_type[i];
        const value = frame?.analog_input[i];
        const unit = analogUnit(typeInfo, type);
        return (
          <div
            key={label}
            className="analog"
            data-testid={`ai-${channelNumber(label)}`}
            data-value={value ?? ""}
            data-type={analogTypeName(typeInfo, type) ?? ""}
          >
            <span className="analog__label" title={tagLabel(label, tags[`analog_input.${i}`])}>
              {label}
            </span>
            <span className="analog__type">{analogTypeName(typeInfo, type) ?? "—"}</span>
            <span className="analog__value">
              {formatAnalog(value)} <span className="analog__unit">{unit}</span>
            </span>
          </div>
        );
      })}
    </div>
  );
}
