/**
 * A writable bit: digital output, tool output or bit input register. Shows *pending* until the
 * backend confirms, then the robot's actual state; the command being sent beside it; a refusal
 * or timeout reason next to it.
 */
import { memo } from "react";
import type { CommandFieldName } from "../generated/layout";
import { useTagNames } from "../components/tagNames";
import { tagLabel } from "../lib/alarms/alarms";
import { bitClickRequest, bitWriteQuestion } from "../lib/layout/tags";
import { writeKey } from "../lib/writes/writes";
import { useWrites, useWriteView } from "./writeContext";

type BitField = Extract<CommandFieldName, "controlbox_do" | "tool_do" | "bit_input_registers">;

interface Props {
  readonly field: BitField;
  readonly index: number;
  readonly label: string;
  readonly testId: string;
  /** The robot's actual state (outputs: from the frame; registers: the image that went out). */
  readonly actual: boolean | null;
  /** The command image's value. */
  readonly command: boolean | null;
  readonly kind: "output" | "register";
  readonly compact?: boolean;
}

export const OutputToggle = memo(function OutputToggle({
  field,
  index,
  label,
  testId,
  actual,
  command,
  kind,
  compact = false,
}: Props) {
  const writes = useWrites();
  const key = writeKey(field, index);
  const view = useWriteView(key, actual);
  const tag = useTagNames()[key];
  // "DO 3 — gripper close" in the question and the tooltip; registers' compact label is a number.
  const named = tagLabel(kind === "register" ? `Register ${label}` : label, tag);
  const state = view.shown === "pending" ? "pending" : view.shown === true ? "on" : "off";
  const mismatch = !view.pending && actual !== null && command !== null && actual !== command;

  const onClick = () => {
    const requested = bitClickRequest(view.shown, actual, command);
    const ask = kind === "output" || writes.confirmRegisters;
    const message = bitWriteQuestion(kind, label, tag, requested);
    void writes.write([key], [requested], { [field]: { [String(index)]: requested } }, ask ? message : null);
  };

  const title = writes.blockReason ?? `${named}: actual ${actual === null ? "unknown" : actual ? "on" : "off"}, command ${command === null ? "unknown" : command ? "on" : "off"}`;
  return (
    <div className={`toggle-cell${compact ? " toggle-cell--compact" : ""}`}>
      <button
        type="button"
        className={`toggle toggle--${state}${mismatch ? " toggle--mismatch" : ""}`}
        data-testid={testId}
        data-state={state}
        data-command={command === null ? "" : command ? "on" : "off"}
        data-write="true"
        aria-pressed={state === "pending" ? "mixed" : state === "on"}
        // The name is the visible text (label, tag, state, command: WCAG 2.5.3); a register's
        // compact button shows its number alone, so its name says what the number is.
        aria-label={compact ? `${kind === "register" ? `Bit input register ${tagLabel(label, tag)}` : named} ${state}` : undefined}
        disabled={!writes.canWrite || view.pending}
        title={title}
        onClick={onClick}
      >
        <span className="toggle__light" aria-hidden="true" />
        <span className="toggle__label">{label}</span>
        {!compact && tag !== undefined && tag !== "" && (
          <span className="toggle__tag" data-testid={`${testId}-tag`}>
            {tag}
          </span>
        )}
        {!compact && <span className="toggle__state">{state === "pending" ? "…" : state.toUpperCase()}</span>}
        {!compact && kind === "output" && (
          <span className="toggle__command" title="command being sent">
            cmd {command === null ? "—" : command ? "on" : "off"}
          </span>
        )}
      </button>
      {view.reason !== null && (
        <span className="reason" data-testid={`${testId}-reason`} role="alert" title={view.reason}>
          {view.phase === "timeout" ? "timeout: " : "refused: "}
          {view.reason}
          <button type="button" className="reason__dismiss" aria-label="dismiss" onClick={() => writes.tracker.clear(key)}>
            ×
          </button>
        </span>
      )}
    </div>
  );
});
