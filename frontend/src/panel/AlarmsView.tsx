/**
 * The panel's alarms: the robot's current alarms (from the stream: no polling) with Acknowledge
 * and Shelve (a reason and a duration) for operators, "Acknowledge all shown" (one request,
 * `POST /api/v1/alarms/ack`, which the service audits alarm by alarm), alarms suppressed by
 * design shown as such (a consequence of their cause, nothing to acknowledge), and the history
 * of every transition with filters (priority, period) and a CSV export, from
 * `GET /api/v1/alarms/history`.
 */
import { memo, useCallback, useState, type FormEvent } from "react";
import { FilterSelect, PagedTable, usePage } from "../components/PagedTable";
import { alarmHistoryCsvUrl, alarmsApi, type HistoryFilter } from "../lib/alarms/alarmsApi";
import {
  ALARM_PRIORITIES,
  alarmPaint,
  alarmStateWords,
  alarmTitle,
  defaultShelveChoice,
  isUnacknowledged,
  shelveChoices,
  shelveRefusal,
  tagLabel,
  type Alarm,
  type AlarmPriority,
} from "../lib/alarms/alarms";
import { acknowledgeable, suppressionWords } from "../lib/alarms/alarmsCell";
import { formatMoment, formatTimestamp } from "../lib/common/dates";
import { roleAtLeast, type User } from "../lib/api/protocol";
import { printSection } from "../lib/history/searchPrint";

const PERIODS = [
  ["hour", "last hour", 3600],
  ["day", "last 24 h", 86_400],
  ["week", "last 7 days", 7 * 86_400],
  ["all", "everything", null],
] as const;
type Period = (typeof PERIODS)[number][0];
const PERIOD_CHOICES = PERIODS.map(([p, words]) => [p, words] as const);
const NO_FILTER: HistoryFilter = { priority: null, since: null, until: null };

const HISTORY_PAGE = 100;

function value(v: boolean | number | null, unit: string): string {
  if (v === null) return "";
  if (typeof v === "boolean") return v ? "on" : "off";
  return unit !== "" ? `${v} ${unit}` : String(v);
}

function ShelveForm({ alarm, onDone }: { alarm: Alarm; onDone: () => void }) {
  const [reason, setReason] = useState("");
  // Only the durations this alarm's priority allows (the service refuses longer ones, 422).
  const choices = shelveChoices(alarm);
  const [duration_s, setDuration] = useState<number>(defaultShelveChoice(choices) ?? 0);
  const [busy, setBusy] = useState(false);
  const [error, setError] = useState<string | null>(null);
  const submit = async (e: FormEvent) => {
    e.preventDefault();
    if (reason.trim() === "") {
      setError("say why it is shelved");
      return;
    }
    setBusy(true);
    const answer = await alarmsApi.shelve(alarm.id, reason.trim(), duration_s).catch((x: unknown) => ({ ok: false as const, reason: String(x) }));
    setBusy(false);
    if (answer.ok) onDone();
    else setError(answer.reason);
  };
  return (
    <form className="alarm-shelve" onSubmit={(e) => void submit(e)} aria-label={`Shelve ${alarm.name}`}>
      <input
        aria-label="Reason for shelving"
        placeholder="reason (required)"
        data-testid="alarm-shelve-reason"
        value={reason}
        onChange={(e) => {
          setReason(e.target.value);
          setError(null);
        }}
      />
      <select aria-label="Shelve for" data-testid="alarm-shelve-duration" value={duration_s} onChange={(e) => setDuration(Number(e.target.value))}>
        {choices.map(([s, words]) => (
          <option key={s} value={s}>
            {words}
          </option>
        ))}
      </select>
      <button type="submit" data-testid="alarm-shelve-submit" disabled={busy}>
        Shelve
      </button>
      <button type="button" onClick={onDone} disabled={busy}>
        Cancel
      </button>
      {error !== null && (
        <span className="reason" role="alert" data-testid="alarm-shelve-error">
          {error}
        </span>
      )}
    </form>
  );
}

function AlarmRow({ alarm, canAct }: { alarm: Alarm; canAct: boolean }) {
  const [shelving, setShelving] = useState(false);
  const [busy, setBusy] = useState(false);
  const [error, setError] = useState<string | null>(null);
  const paint = alarmPaint(alarm.colour);
  const unacknowledged = isUnacknowledged(alarm);
  const suppression = suppressionWords(alarm);
  // A safety stop or a critical alarm is never shelved (ISA-18.2): no Shelve, the reason instead.
  const notShelvable = shelveRefusal(alarm);
  const act = async (action: () => Promise<{ ok: boolean; reason?: string }>) => {
    setBusy(true);
    setError(null);
    const answer = await action().catch((x: unknown) => ({ ok: false, reason: String(x) }));
    setBusy(false);
    if (!answer.ok) setError(answer.reason ?? "refused");
  };
  return (
    <tr
      data-testid="alarm-row"
      data-alarm={alarm.id}
      data-priority={alarm.priority}
      data-state={alarm.state}
      data-unacknowledged={unacknowledged ? "true" : "false"}
      data-shelved={alarm.shelved ? "true" : "false"}
      data-suppressed-by={alarm.suppressed_by ?? undefined}
      className={`alarm-row${unacknowledged ? " is-unacknowledged" : ""}${alarm.shelved ? " is-shelved" : ""}${suppression !== null ? " is-suppressed" : ""}`}
    >
      <td>
        {/* A suppressed alarm is not annunciated: no pendant colour. */}
        <span className="alarm-priority" style={suppression === null ? { background: paint.background, color: paint.text } : undefined}>
          {alarm.priority}
        </span>
      </td>
      <td>
        <strong>{alarmTitle(alarm)}</strong>
        {alarm.message !== null && alarm.message !== "" && <div className="alarm-row__message">{alarm.message}</div>}
      </td>
      <td data-testid="alarm-state">
        {unacknowledged && (
          <span className="alarm-unack-mark" data-testid="alarm-unack-mark" aria-hidden="true">
            ●{" "}
          </span>
        )}
        {suppression ?? alarmStateWords(alarm)}
        {alarm.shelved && alarm.shelved_until !== null && (
          <div className="hint">
            until {formatMoment(alarm.shelved_until * 1000, Date.now())} by {alarm.shelved_by ?? "?"}: {alarm.shelve_reason ?? ""}
          </div>
        )}
        {alarm.acknowledged_by !== null && !unacknowledged && (
          <div className="hint">
            acknowledged by {alarm.acknowledged_by}
            {alarm.ack_comment ? `: ${alarm.ack_comment}` : ""}
          </div>
        )}
      </td>
      <td className="nowrap">{alarm.activated_at !== null ? formatTimestamp(alarm.activated_at) : ""}</td>
      <td className="alarm-row__actions">
        {unacknowledged && (
          <button
            type="button"
            className="primary"
            data-testid="alarm-ack"
            disabled={!canAct || busy}
            title={canAct ? undefined : "Log in as an operator to acknowledge"}
            onClick={() => void act(() => alarmsApi.ack(alarm.id, null))}
          >
            Acknowledge
          </button>
        )}
        {alarm.shelved ? (
          <button type="button" data-testid="alarm-unshelve" disabled={!canAct || busy} onClick={() => void act(() => alarmsApi.unshelve(alarm.id))}>
            Unshelve
          </button>
        ) : notShelvable !== null ? (
          <span className="hint" data-testid="alarm-shelve-refused" title={notShelvable}>
            never shelved
          </span>
        ) : (
          !shelving && (
            <button type="button" data-testid="alarm-shelve" disabled={!canAct || busy} onClick={() => setShelving(true)}>
              Shelve…
            </button>
          )
        )}
        {shelving && <ShelveForm alarm={alarm} onDone={() => setShelving(false)} />}
        {error !== null && (
          <span className="reason" role="alert" data-testid="alarm-action-error">
            {error}
          </span>
        )}
      </td>
    </tr>
  );
}

function AlarmHistory({ robot, newest }: { robot: string; newest: number | null }) {
  const [priority, setPriority] = useState<AlarmPriority | "">("");
  const [period, setPeriod] = useState<Period>("day");
  const seconds = PERIODS.find(([p]) => p === period)?.[2] ?? null;
  // The period's start is fixed when the page is asked for; the answer carries the filter it
  // asked with, for the CSV link.
  const request = useCallback(() => {
    const filter: HistoryFilter = {
      priority: priority === "" ? null : priority,
      since: seconds === null ? null : Math.floor(Date.now() / 1000) - seconds,
      until: null,
    };
    return alarmsApi.history(robot, filter, HISTORY_PAGE, 0).then((answer) => ({ ...answer, filter }));
  }, [robot, priority, seconds]);
  // Asked again when the filter changes or an alarm changes (the stream's newest alarm event).
  const { page, error, answer } = usePage(request, { what: "history", refresh: newest });
  const asked = answer?.filter ?? NO_FILTER;

  return (
    <PagedTable
      filters={
        <>
          <FilterSelect label="priority" testId="alarm-history-priority" value={priority} options={ALARM_PRIORITIES} onChange={setPriority} />
          <FilterSelect
            label="period"
            testId="alarm-history-period"
            value={period}
            options={PERIOD_CHOICES}
            all={null}
            onChange={(p) => setPeriod(p === "" ? "day" : p)}
          />
          <button type="button" data-testid="alarm-history-print" onClick={() => printSection("alarms")}>
            Print
          </button>
        </>
      }
      source={page !== null ? `${page.total} transitions, newest ${HISTORY_PAGE} shown` : "loading…"}
      csv={{ testId: "alarm-history-csv", href: alarmHistoryCsvUrl(robot, asked) }}
      error={error}
      label="Alarm history"
      testId="alarm-history-table"
      columns={["time", "priority", "alarm", "transition", "state after", "value", "user", "comment"]}
      rows={page?.items ?? []}
      row={(row) => (
        <tr key={row.id} data-testid="alarm-history-row" data-transition={row.transition} data-priority={row.priority}>
          <td className="nowrap">{formatTimestamp(row.time)}</td>
          <td>{row.priority}</td>
          <td>
            {row.name}
            {tagLabel(row.label, row.tag) !== "" && !row.name.includes(tagLabel(row.label, row.tag)) ? ` · ${tagLabel(row.label, row.tag)}` : ""}
            {row.message !== null && row.message !== "" && <div className="hint">{row.message}</div>}
          </td>
          <td>{row.transition.replaceAll("_", " ")}</td>
          <td>{alarmStateWords(row)}</td>
          <td>{row.value_words ?? value(row.value, "")}</td>
          <td>{row.user ?? ""}</td>
          <td>{row.comment ?? ""}</td>
        </tr>
      )}
      empty="no alarm transitions"
    />
  );
}

/** "Acknowledge all shown": the list's unacknowledged, annunciated alarms in one request. */
function AcknowledgeAll({ alarms, canAct }: { readonly alarms: readonly Alarm[]; readonly canAct: boolean }) {
  const [busy, setBusy] = useState(false);
  const [outcome, setOutcome] = useState<{ readonly ok: boolean; readonly words: string } | null>(null);
  const ids = acknowledgeable(alarms);
  const run = async () => {
    setBusy(true);
    setOutcome(null);
    const answer = await alarmsApi.ackMany(ids, null).catch((x: unknown) => ({ ok: false as const, status: 0, reason: String(x) }));
    setBusy(false);
    if (!answer.ok) {
      setOutcome({ ok: false, words: answer.reason });
      return;
    }
    const refused = answer.page.items.filter((item) => item.outcome === "refused");
    const words = `${answer.page.acknowledged} acknowledged${refused.length > 0 ? `, ${refused.length} refused: ${refused.map((r) => r.reason ?? r.id).join("; ")}` : ""}`;
    setOutcome({ ok: refused.length === 0, words });
  };
  return (
    <div className="alarm-table-actions">
      <button
        type="button"
        className="primary"
        data-testid="alarm-ack-all"
        data-count={ids.length}
        disabled={!canAct || busy || ids.length === 0}
        title={canAct ? undefined : "Log in as an operator to acknowledge"}
        onClick={() => void run()}
      >
        Acknowledge all shown ({ids.length})
      </button>
      {outcome !== null && (
        <span className={outcome.ok ? "hint" : "reason"} role={outcome.ok ? "status" : "alert"} data-testid="alarm-ack-all-outcome">
          {outcome.words}
        </span>
      )}
    </div>
  );
}

// Memoized: the panel re-renders with every live snapshot; this only when the alarms change.
export const AlarmsView = memo(function AlarmsView({
  robot,
  user,
  alarms,
  newestEvent,
}: {
  readonly robot: string;
  readonly user: User | null;
  readonly alarms: readonly Alarm[];
  /** Time of the stream's newest `alarm` event (the history is asked again when it changes). */
  readonly newestEvent: number | null;
}) {
  const canAct = roleAtLeast(user, "operator");
  return (
    <div className="alarms-view">
      {!canAct && <p className="hint">Log in as an operator to acknowledge or shelve alarms.</p>}
      <AcknowledgeAll alarms={alarms} canAct={canAct} />
      <div className="table-scroll" tabIndex={0} role="region" aria-label="Alarms">
        <table data-testid="alarm-table" className="alarm-table">
          <thead>
            <tr>
              <th>priority</th>
              <th>alarm</th>
              <th>state</th>
              <th>since</th>
              <th>actions</th>
            </tr>
          </thead>
          <tbody>
            {alarms.map((alarm) => (
              <AlarmRow key={alarm.id} alarm={alarm} canAct={canAct} />
            ))}
            {alarms.length === 0 && (
              <tr>
                <td colSpan={5} className="empty" data-testid="alarms-none">
                  no alarms
                </td>
              </tr>
            )}
          </tbody>
        </table>
      </div>
      <h3>History</h3>
      <AlarmHistory robot={robot} newest={newestEvent} />
    </div>
  );
});
