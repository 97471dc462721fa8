/**
 * The robot's baselines (who set each, when and why, what it was learned from, the one in use
 * and the one being learned) and the form that asks for a new one: a reason (required: the
 * audit keeps it) and what to learn from: the next N cycles, or a period already recorded (from,
 * to). Offered to operators only; the service's refusal is said beside the form in words
 * (lib/health/baselines.ts).
 */
import { useState, type FormEvent } from "react";
import { errorReason } from "../lib/api/api";
import type { User } from "../lib/api/protocol";
import { DEFAULT_BASELINE_CYCLES, MAX_BASELINE_CYCLES, MAX_BASELINE_PERIOD_DAYS, MIN_BASELINE_CYCLES, baselineBlockedReason, baselineRefusalWords, baselineRows, checkBaselineForm, checkPeriodBaselineForm } from "../lib/health/baselines";
import { healthApi } from "../lib/health/healthApi";
import type { BaselineRecord } from "../lib/health/healthTypes";

interface Props {
  readonly robot: string;
  readonly user: User | null;
  /** Every baseline of the robot (null: not read yet). */
  readonly baselines: readonly BaselineRecord[] | null;
  /** Why the list could not be read (null: it could). */
  readonly error: string | null;
  /** A new baseline was asked for: the report is asked again at once. */
  readonly onAsked: () => void;
}

type Mode = "cycles" | "period";
type Field = "reason" | "cycles" | "from" | "to";

/** The fields of a recorded period: from and to as the page's date-time inputs type them. */
function PeriodFields({ from, to, error, onFrom, onTo }: { readonly from: string; readonly to: string; readonly error: Field | null; readonly onFrom: (v: string) => void; readonly onTo: (v: string) => void }) {
  return (
    <>
      <label>
        <span>from</span>
        <input data-testid="baseline-from" type="datetime-local" step={1} value={from} aria-invalid={error === "from"} onChange={(e) => onFrom(e.target.value)} />
      </label>
      <label>
        <span>to</span>
        <input data-testid="baseline-to" type="datetime-local" step={1} value={to} aria-invalid={error === "to"} onChange={(e) => onTo(e.target.value)} />
      </label>
    </>
  );
}

function BaselineForm({ robot, onAsked }: { readonly robot: string; readonly onAsked: () => void }) {
  const [reason, setReason] = useState("");
  const [mode, setMode] = useState<Mode>("cycles");
  const [cycles, setCycles] = useState(String(DEFAULT_BASELINE_CYCLES));
  const [from, setFrom] = useState("");
  const [to, setTo] = useState("");
  const [busy, setBusy] = useState(false);
  const [error, setError] = useState<{ field: Field | null; words: string } | null>(null);
  const [done, setDone] = useState<string | null>(null);

  const submit = async (e: FormEvent) => {
    e.preventDefault();
    setDone(null);
    const check = mode === "cycles" ? checkBaselineForm(reason, cycles) : checkPeriodBaselineForm(reason, from, to);
    if (!check.ok) {
      setError({ field: check.field, words: check.reason });
      return;
    }
    setBusy(true);
    setError(null);
    try {
      const answer = await healthApi.setBaseline(robot, check.body);
      if (answer.status >= 200 && answer.status < 300) {
        setReason("");
        setDone(
          mode === "cycles"
            ? `Learning a new baseline from the next ${cycles.trim()} cycles; the one in use stays until it is learned.`
            : "Learned a new baseline from the recorded period: it is in use now.",
        );
        onAsked();
      } else {
        setError({ field: null, words: baselineRefusalWords(answer.status, errorReason(answer)) });
      }
    } catch (err) {
      setError({ field: null, words: `The service did not answer: ${err instanceof Error ? err.message : String(err)}` });
    } finally {
      setBusy(false);
    }
  };

  return (
    <form className="health-baseline-form" onSubmit={(e) => void submit(e)} aria-labelledby="baseline-form-title" data-testid="baseline-form" noValidate>
      <h3 id="baseline-form-title">Set a new baseline</h3>
      <p className="hint">After a reducer change or a new program: the robot's next cycles, or those of a period already recorded, become its healthy reference. The old baselines are kept.</p>
      <fieldset className="health-baseline-form__mode" data-testid="baseline-mode">
        <legend>learn from</legend>
        <label>
          <input type="radio" name="baseline-mode" data-testid="baseline-mode-cycles" checked={mode === "cycles"} onChange={() => setMode("cycles")} /> the next N cycles
        </label>
        <label>
          <input type="radio" name="baseline-mode" data-testid="baseline-mode-period" checked={mode === "period"} onChange={() => setMode("period")} /> a recorded period (from, to; at most {MAX_BASELINE_PERIOD_DAYS} days)
        </label>
      </fieldset>
      <div className="health-baseline-form__fields">
        <label>
          <span>reason (required)</span>
          <input
            data-testid="baseline-reason"
            value={reason}
            required
            aria-invalid={error?.field === "reason"}
            aria-describedby={error !== null ? "baseline-error" : undefined}
            placeholder="J3 reducer replaced"
            onChange={(e) => setReason(e.target.value)}
          />
        </label>
        {mode === "cycles" ? (
          <label>
            <span>cycles to learn from</span>
            <input
              data-testid="baseline-cycles"
              type="number"
              inputMode="numeric"
              min={MIN_BASELINE_CYCLES}
              max={MAX_BASELINE_CYCLES}
              step={1}
              value={cycles}
              aria-invalid={error?.field === "cycles"}
              aria-describedby={error !== null ? "baseline-error" : undefined}
              onChange={(e) => setCycles(e.target.value)}
            />
          </label>
        ) : (
          <PeriodFields from={from} to={to} error={error?.field ?? null} onFrom={setFrom} onTo={setTo} />
        )}
        <button type="submit" className="primary" data-testid="baseline-submit" disabled={busy}>
          Learn a new baseline
        </button>
      </div>
      {error !== null && (
        <p id="baseline-error" className="reason" role="alert" data-testid="baseline-error">
          {error.words}
        </p>
      )}
      {done !== null && (
        <p className="hint" role="status" data-testid="baseline-asked">
          {done}
        </p>
      )}
    </form>
  );
}

export function BaselinesView({ robot, user, baselines, error, onAsked }: Props) {
  const rows = baselineRows(baselines ?? []);
  const blocked = baselineBlockedReason(user);
  return (
    <div className="health-baselines">
      {error !== null && (
        <p className="reason" data-testid="health-baselines-error">
          The baselines could not be read: {error}
        </p>
      )}
      {baselines === null ? null : rows.length === 0 ? (
        <p data-testid="health-baselines-none">No baseline yet: the robot's verdicts start once one is learned.</p>
      ) : (
        <div className="table-scroll" tabIndex={0} role="region" aria-label="baselines">
          <table data-testid="health-baselines">
            <caption>Baselines, newest first</caption>
            <thead>
              <tr>
                <th scope="col">#</th>
                <th scope="col">set by</th>
                <th scope="col">why</th>
                <th scope="col">started</th>
                <th scope="col">learned</th>
                <th scope="col">from</th>
                <th scope="col">state</th>
              </tr>
            </thead>
            <tbody>
              {rows.map((row) => (
                <tr key={`${row.id}-${row.learning ? "l" : "k"}`} data-testid="health-baseline-row" data-in-use={row.inUse ? "true" : "false"} data-learning={row.learning ? "true" : "false"}>
                  <td>{row.id}</td>
                  <td data-testid="health-baseline-by">{row.by}</td>
                  <td data-testid="health-baseline-reason">{row.reason}</td>
                  <td className="nowrap">{row.started}</td>
                  <td className="nowrap">{row.finished}</td>
                  <td>{row.learnedFrom}</td>
                  <td>{row.learning ? "being learned" : row.inUse ? "in use" : "kept"}</td>
                </tr>
              ))}
            </tbody>
          </table>
        </div>
      )}
      <div className="no-print">
        {blocked !== null ? (
          <p className="hint" data-testid="baseline-blocked">
            {blocked}
          </p>
        ) : (
          <BaselineForm robot={robot} onAsked={onAsked} />
        )}
      </div>
    </div>
  );
}
