/**
 * Analog outputs: actual value with its type and unit, the command being sent, and a setpoint
 * field with a type choice. The setpoint is checked against the layout's range for the chosen
 * type before the confirmation is asked (a decimal comma is accepted); the refusal goes away as
 * soon as a valid value is typed. The backend checks again (its refusal is shown here too).
 */
import { useState } from "react";
import type { Frame } from "../generated/layout";
import { analogRange, analogTypeName, analogUnit, channelNumber, commandField, frameField } from "../lib/layout/layoutInfo";
import { checkSetpoint } from "../lib/writes/writeChecks";
import { writeKey, type WriteValue } from "../lib/writes/writes";
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
  // What is shown: the written value and type from their confirmation on (lib/writes/writes.ts), the
  // robot's frame otherwise; the type's name and the unit follow the type shown.
  const shownValue = typeof valueView.shown === "number" ? valueView.shown : null;
  const shownType = typeof typeView.shown === "number" ? typeView.shown : actualType;
  const type = chosenType ?? actualType ?? commandType ?? 0;
  const range = analogRange(typeField, type);
  const pending = valueView.pending || typeView.pending;
  const reason = localReason ?? valueView.reason ?? typeView.reason;
  const testId = `ao-${channelNumber(label)}`;

  // A refusal (ours or the service's) stays only while the typed value is still not valid.
  const recheck = (text: string, forType: number) => {
    if (localReason === null && valueView.reason === null) return;
    const checked = checkSetpoint(text, analogRange(typeField, forType));
    if (checked.ok) {
      setLocalReason(null);
      writes.tracker.clear(valueKey);
      writes.tracker.clear(typeKey);
    } else if (localReason !== null) {
      setLocalReason(checked.reason);
    }
  };

  const submit = () => {
    const checked = checkSetpoint(setpoint, range);
    if (!checked.ok) {
      setLocalReason(checked.reason);
      return;
    }
    const value = checked.value;
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
      data-value={pending ? (actual ?? "") : (shownValue ?? "")}
      data-type={analogTypeName(typeField, pending ? actualType : shownType) ?? ""}
    >
      <span className="analog__label">{label}</span>
      <span className="analog__type">{analogTypeName(typeField, pending ? actualType : shownType) ?? "—"}</span>
      <span className="analog__value" data-testid={`${testId}-actual`}>
        {pending ? "…" : formatAnalog(shownValue)} <span className="analog__unit">{analogUnit(typeField, pending ? actualType : shownType)}</span>
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
          onChange={(e) => {
            const next = Number(e.target.value);
            setChosenType(next);
            recheck(setpoint, next);
          }}
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
          aria-invalid={localReason !== null}
          aria-describedby={reason !== null ? `${testId}-reason` : undefined}
          onChange={(e) => {
            setSetpoint(e.target.value);
            recheck(e.target.value, type);
          }}
        />
        <button type="submit" data-testid={`${testId}-set`} data-write="true" disabled={!writes.canWrite || pending} title={writes.blockReason ?? ""}>
          Set
        </button>
      </form>
      {reason !== null && (
        <span className="reason" id={`${testId}-reason`} data-testid={`${testId}-reason`} role="alert">
          {localReason === null && (valueView.phase === "timeout" || typeView.phase === "timeout") ? "timeout: " : "refused: "}
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
