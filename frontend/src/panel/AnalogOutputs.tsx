/**
 * Analog outputs: actual value with its type and unit, the command being sent, and a setpoint
 * field with a type choice. The backend validates the range (the refusal is shown here); the
 * layout's range for the chosen type is shown as a hint.
 */
import { useState } from "react";
import type { Frame } from "../generated/layout";
import { analogRange, analogTypeName, analogUnit, channelNumber, commandField, frameField } from "../lib/layoutInfo";
import { writeKey, type WriteValue } from "../lib/writes";
import { formatAnalog } from "../components/IoView";
import { useWrites, useWriteView } from "./writeContext";

function AnalogOutput({ index, label, frame }: { index: number; label: string; frame: Frame | null }) {
  const writes = useWrites();
  const typeField = commandField("analog_output_type");
  const valueKey = writeKey("analog_output", index);
  const typeKey = writeKey("analog_output_type", index);
  const actual = frame?.analog_output[index] ?? null;
  const actualType = frame?.analog_output_type[index] ?? null;
  const command = writes.command?.image.analog_output[index] ?? null;
  const commandType = writes.command?.image.analog_output_type[index] ?? null;
  const valueView = useWriteView(valueKey, actual);
  const typeView = useWriteView(typeKey, actualType);
  const [setpoint, setSetpoint] = useState("");
  const [chosenType, setChosenType] = useState<number | null>(null);
  const [localReason, setLocalReason] = useState<string | null>(null);
  const type = chosenType ?? actualType ?? commandType ?? 0;
  const range = analogRange(typeField, type);
  const pending = valueView.pending || typeView.pending;
  const reason = localReason ?? valueView.reason ?? typeView.reason;
  const testId = `ao-${channelNumber(label)}`;

  const submit = () => {
    const value = Number(setpoint.trim());
    if (setpoint.trim() === "" || !Number.isFinite(value)) {
      setLocalReason("enter a number");
      return;
    }
    setLocalReason(null);
    const keys: string[] = [];
    const values: WriteValue[] = [];
    const patch: { analog_output_type?: Record<string, number>; analog_output: Record<string, number> } = {
      analog_output: { [String(index)]: value },
    };
    if (type !== actualType) {
      patch.analog_output_type = { [String(index)]: type };
      keys.push(typeKey);
      values.push(type);
    }
    keys.push(valueKey);
    values.push(value);
    const unit = range?.unit ?? "";
    const message = `Set ${label} to ${value} ${unit} (${analogTypeName(typeField, type) ?? "?"})?`;
    void writes.write(keys, values, patch, message);
  };

  return (
    <div
      className={`analog analog--output${pending ? " is-pending" : ""}`}
      data-testid={testId}
      data-state={pending ? "pending" : "idle"}
      data-value={actual ?? ""}
      data-type={analogTypeName(typeField, actualType) ?? ""}
    >
      <span className="analog__label">{label}</span>
      <span className="analog__type">{analogTypeName(typeField, actualType) ?? "—"}</span>
      <span className="analog__value" data-testid={`${testId}-actual`}>
        {pending ? "…" : formatAnalog(valueView.shown === "pending" ? null : (valueView.shown as number | null))}{" "}
        <span className="analog__unit">{analogUnit(typeField, actualType)}</span>
      </span>
      <span className="analog__command" title="command being sent">
        cmd {formatAnalog(command)} {analogUnit(typeField, commandType)}
      </span>
      <form
        className="analog__setpoint"
        onSubmit={(e) => {
          e.preventDefault();
          submit();
        }}
      >
        <select
          aria-label={`${label} type`}
          data-testid={`${testId}-type`}
          data-write="true"
          value={type}
          disabled={!writes.canWrite || pending}
          onChange={(e) => setChosenType(Number(e.target.value))}
        >
          {(typeField.value_names ?? []).map((name, v) => (
            <option key={name} value={v}>
              {name}
            </option>
          ))}
        </select>
        <input
          type="text"
          inputMode="decimal"
          aria-label={`${label} setpoint`}
          data-testid={`${testId}-setpoint`}
          data-write="true"
          placeholder={range !== null ? `${range.low}–${range.high} ${range.unit}` : ""}
          value={setpoint}
          disabled={!writes.canWrite || pending}
          onChange={(e) => setSetpoint(e.target.value)}
        />
        <button type="submit" data-testid={`${testId}-set`} data-write="true" disabled={!writes.canWrite || pending} title={writes.blockReason ?? ""}>
          Set
        </button>
      </form>
      {reason !== null && (
        <span className="reason" data-testid={`${testId}-reason`} role="alert">
          {valueView.phase === "timeout" || typeView.phase === "timeout" ? "timeout: " : "refused: "}
          {reason}
        </span>
      )}
    </div>
  );
}

export function AnalogOutputs({ frame }: { readonly frame: Frame | null }) {
  const info = frameField("analog_output");
  return (
    <div className="analog-list">
      {info.channels.map((label, i) => (
        <AnalogOutput key={label} index={i} label={label} frame={frame} />
      ))}
    </div>
  );
}
