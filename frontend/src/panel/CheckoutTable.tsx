/**
 * The points of one checkout: label, tag name, result, what the frames or the robot showed, who
 * and when, the checker's comment; on an open checkout the actions of each point (switch an
 * output, capture an analog input, pass or fail with a comment). The actions are screen-only:
 * the print stylesheet (styles/print.css) hides every button and input.
 */
import { memo, useState } from "react";
import { evidenceWords, pointTime_s, pointWho, verdictRefusal, type CheckoutPoint } from "../lib/commissioning/checkout";
import { formatTimestamp } from "../lib/common/dates";

export interface PointActions {
  readonly switchOutput: (p: CheckoutPoint, value: boolean | number) => void;
  readonly capture: (p: CheckoutPoint) => void;
  readonly record: (p: CheckoutPoint, result: "pass" | "fail", comment: string) => void;
}

function OutputSwitch({ point, busy, actions }: { readonly point: CheckoutPoint; readonly busy: boolean; readonly actions: PointActions }) {
  const [value, setValue] = useState("");
  if (point.signal === "analog") {
    return (
      <span className="checkout__switch">
        <input
          aria-label={`Value for ${point.label}`}
          data-testid="checkout-ao-value"
          inputMode="decimal"
          size={5}
          value={value}
          onChange={(e) => setValue(e.target.value)}
        />
        <button type="button" disabled={busy || value.trim() === "" || !Number.isFinite(Number(value))} onClick={() => actions.switchOutput(point, Number(value))}>
          Set
        </button>
      </span>
    );
  }
  return (
    <span className="checkout__switch">
      <button type="button" data-testid="checkout-switch-on" disabled={busy} onClick={() => actions.switchOutput(point, true)}>
        On
      </button>
      <button type="button" data-testid="checkout-switch-off" disabled={busy} onClick={() => actions.switchOutput(point, false)}>
        Off
      </button>
    </span>
  );
}

const Row = memo(function Row({
  point,
  open,
  busy,
  actions,
}: {
  readonly point: CheckoutPoint;
  readonly open: boolean;
  readonly busy: boolean;
  readonly actions: PointActions;
}) {
  const [comment, setComment] = useState("");
  const time_s = pointTime_s(point);
  const failRefused = verdictRefusal("fail", comment);
  return (
    <tr data-testid="checkout-row" data-key={point.key} data-result={point.result}>
      <td className="nowrap">{point.label}</td>
      <td>{point.tag ?? ""}</td>
      <td>{point.kind}</td>
      <td className={`checkout__result is-${point.result}`} data-testid="checkout-result">
        {point.result}
      </td>
      <td data-testid="checkout-evidence">{evidenceWords(point)}</td>
      <td className="nowrap">{time_s === null ? "" : formatTimestamp(time_s)}</td>
      <td>{pointWho(point)}</td>
      <td>
        {point.comment ?? ""}
        {open && (
          <input
            aria-label={`Comment on ${point.label}`}
            data-testid="checkout-comment"
            maxLength={500}
            placeholder="comment"
            value={comment}
            onChange={(e) => setComment(e.target.value)}
          />
        )}
      </td>
      {open && (
        <td className="nowrap checkout__actions">
          {point.kind === "output" && <OutputSwitch point={point} busy={busy} actions={actions} />}
          {point.kind === "input" && point.signal === "analog" && (
            <button type="button" data-testid="checkout-capture" disabled={busy} onClick={() => actions.capture(point)}>
              Capture
            </button>
          )}
          <button type="button" data-testid="checkout-pass" disabled={busy} onClick={() => actions.record(point, "pass", comment)}>
            Pass
          </button>
          <button
            type="button"
            data-testid="checkout-fail"
            disabled={busy || failRefused !== null}
            title={failRefused ?? `Record ${point.label} as failed`}
            onClick={() => actions.record(point, "fail", comment)}
          >
            Fail
          </button>
        </td>
      )}
    </tr>
  );
});

export function CheckoutTable({
  points,
  open,
  busy,
  actions,
}: {
  readonly points: readonly CheckoutPoint[];
  readonly open: boolean;
  readonly busy: boolean;
  readonly actions: PointActions;
}) {
  return (
    <div className="table-scroll" tabIndex={0} role="region" aria-label="Checkout points">
      <table data-testid="checkout-table" className="checkout__table">
        <thead>
          <tr>
            <th>point</th>
            <th>tag</th>
            <th>kind</th>
            <th>result</th>
            <th>seen / switched and confirmed</th>
            <th>when</th>
            <th>who</th>
            <th>comment</th>
            {open && <th className="no-print">actions</th>}
          </tr>
        </thead>
        <tbody>
          {points.map((p) => (
            <Row key={p.key} point={p} open={open} busy={busy} actions={actions} />
          ))}
        </tbody>
      </table>
    </div>
  );
}
