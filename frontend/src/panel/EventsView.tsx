/**
 * Events and audit tables of the robot shown. Events: the log from the API, searched by text and
 * time range and paged (anyone where the site lets anyone view, else a login), or the live stream
 * when the log cannot be read, filtered by kind; audit: write attempts and control changes
 * (operators), filtered by action. CSV export (of the search) goes through the API.
 */
import { memo, useCallback, useMemo, useState } from "react";
import { FilterSelect, PagedTable, usePage } from "../components/PagedTable";
import { alarmTitle } from "../lib/alarms/alarms";
import { api, auditCsvUrl } from "../lib/api/api";
import { formatTimestamp, timeZoneLabel } from "../lib/common/dates";
import { keyLabel } from "../lib/layout/layoutInfo";
import { EVENT_KINDS, roleAtLeast, type EventKind, type StreamEvent, type User } from "../lib/api/protocol";
import { NO_SEARCH, isSearching, pageWords, searchEvents, searchEventsCsvUrl, type SearchFields } from "../lib/history/search";
import { printSection } from "../lib/history/searchPrint";
import { pointsWords } from "../lib/layout/tags";

const PAGE = 100;

interface Row {
  readonly key: string;
  readonly event: StreamEvent;
}

/**
 * An event in words: the service's own `text` ("Servo on flag cleared", "Robot state Safe off
 * (was Emergency stop)"), as its log, its CSV and a search of it say it (a search looks in these
 * words, so every row it returns shows what was searched); an alarm's priority before them.
 * Without a text (an older service): the panel's words for every kind.
 */
function describe(event: StreamEvent): string {
  if (typeof event.text === "string" && event.text !== "") return event.kind === "alarm" ? `${event.alarm.priority}: ${event.text}` : event.text;
  const s = (v: unknown) => (v === null || v === undefined ? "—" : typeof v === "object" ? JSON.stringify(v) : String(v));
  const because = (reason: string | null | undefined) => (reason ? ` (${reason})` : "");
  switch (event.kind) {
    case "robot_state":
      return `${s(event.from_name ?? event.from)} → ${s(event.to_name)}`;
    case "flag":
      return `${event.label ?? event.flag} flag ${event.value ? "set" : "cleared"}`;
    case "connection":
      return `${event.state}${event.reason ? `: ${event.reason}` : ""}`;
    case "control":
      return `${event.holder?.user ?? "nobody"} holds control${because(event.reason)}`;
    case "write":
      // The service's words name the spec's labels, tags and units ("AO 1 type = voltage, AO 1 = 5 V").
      return `${s(event.user)}: ${event.summary ?? pointsWords(event.fields, event.tags, event.labels)} → ${event.outcome}${because(event.reason)}`;
    case "alarm": {
      const message = (event.transition === "activated" || event.transition === "cleared") && event.alarm.message ? `: ${event.alarm.message}` : "";
      return `${event.alarm.priority} alarm ${alarmTitle(event.alarm)} ${event.transition.replaceAll("_", " ")}${message}${event.user ? ` by ${event.user}` : ""}${because(event.comment)}`;
    }
    case "recording":
      return `recording ${event.state}${event.dropped ? `, ${event.dropped} frames dropped` : ""}${because(event.reason)}`;
    case "session":
      return `${event.user}'s session ended${because(event.reason)}: ${event.streams_closed} stream${event.streams_closed === 1 ? "" : "s"} closed`;
    default:
      // A kind this build does not describe yet (a newer service): its fields as they came.
      return JSON.stringify(event);
  }
}

/** {"controlbox_do.2": true} → "DO 3 = true"; anything else as JSON. */
function values(v: unknown): string {
  if (typeof v === "object" && v !== null && !Array.isArray(v)) {
    return Object.entries(v as Record<string, unknown>)
      .map(([k, x]) => `${keyLabel(k)} = ${typeof x === "object" ? JSON.stringify(x) : String(x)}`)
      .join(", ");
  }
  return short(v);
}

// Memoized: the panel re-renders with every live snapshot; these only when events or the user change.
export const EventsView = memo(function EventsView({
  robot,
  liveEvents,
}: {
  readonly robot: string;
  readonly user: User | null;
  readonly liveEvents: readonly StreamEvent[];
}) {
  const [kind, setKind] = useState<EventKind | "">("");
  const [fields, setFields] = useState<SearchFields>(NO_SEARCH);
  const [offset, setOffset] = useState(0);
  const newest = liveEvents[0];
  const kindAsked = kind === "" ? null : kind;
  // The log, searched, a page at a time; asked again when the search changes or an event arrives.
  // Read without a login where the site lets anyone view (view_requires_login); else live events.
  const request = useCallback(() => searchEvents(api.client, robot, kindAsked, fields, PAGE, offset), [robot, kindAsked, fields, offset]);
  const { page: history, error } = usePage(request, { what: "events", refresh: newest });
  const search = (change: Partial<SearchFields>) => {
    setFields((f) => ({ ...f, ...change }));
    setOffset(0);
  };

  const rows: Row[] = useMemo(() => {
    if (history !== null) return history.items.map((event, i) => ({ key: `log-${event.id ?? `${event.time}-${i}`}`, event }));
    return liveEvents.filter((e) => kind === "" || e.kind === kind).map((event, i) => ({ key: `live-${event.time}-${i}`, event }));
  }, [history, liveEvents, kind]);

  const filters = (
    <>
      <FilterSelect
        label="kind"
        testId="events-kind-filter"
        value={kind}
        options={EVENT_KINDS}
        onChange={(k) => {
          setKind(k);
          setOffset(0);
        }}
      />
      <label>
        text <input type="search" data-testid="events-search" value={fields.text} placeholder="words of the event" onChange={(e) => search({ text: e.target.value })} />
      </label>
      <label>
        from <input type="datetime-local" step={1} data-testid="events-from" value={fields.from} onChange={(e) => search({ from: e.target.value })} />
      </label>
      <label>
        to <input type="datetime-local" step={1} data-testid="events-to" value={fields.to} onChange={(e) => search({ to: e.target.value })} />
      </label>
      <span className="print-only">
        {`Events of ${robot}${fields.text.trim() === "" ? "" : ` matching “${fields.text.trim()}”`}, from ${fields.from.replace("T", " ") || "the first"} to ${fields.to.replace("T", " ") || "now"}, times in ${timeZoneLabel(Date.now())}`}
      </span>
      {history !== null && (
        <span className="no-print">
          <button type="button" data-testid="events-newer" disabled={offset === 0} onClick={() => setOffset(Math.max(0, offset - PAGE))}>
            Newer
          </button>{" "}
          <button type="button" data-testid="events-older" disabled={offset + PAGE >= history.total} onClick={() => setOffset(offset + PAGE)}>
            Older
          </button>{" "}
          <button type="button" onClick={() => printSection("events")}>
            Print
          </button>
        </span>
      )}
    </>
  );
  return (
    <PagedTable
      filters={filters}
      source={
        history !== null
          ? `${pageWords(offset, history.items.length, history.total)} ${isSearching(fields) ? "matching" : "in the log"}`
          : "live events since this page opened (log in to search the log)"
      }
      csv={{ testId: "events-csv", href: searchEventsCsvUrl(robot, kindAsked, fields) }}
      error={history !== null ? error : null}
      label="Events"
      testId="events-table"
      columns={["time", "kind", "what"]}
      rows={rows}
      row={(row) => (
        <tr key={row.key} data-kind={row.event.kind}>
          <td className="nowrap">{formatTimestamp(row.event.time)}</td>
          <td>{row.event.kind}</td>
          <td>{describe(row.event)}</td>
        </tr>
      )}
      empty="no events"
    />
  );
});

function short(v: unknown): string {
  if (v === null || v === undefined) return "";
  return typeof v === "string" ? v : JSON.stringify(v);
}

export const AuditView = memo(function AuditView({
  robot,
  user,
  liveEvents,
}: {
  readonly robot: string;
  readonly user: User | null;
  readonly liveEvents: readonly StreamEvent[];
}) {
  const [action, setAction] = useState("");
  const allowed = roleAtLeast(user, "operator");
  const newestAudited = liveEvents.find((e) => e.kind === "write" || e.kind === "control" || (e.kind === "alarm" && e.user));
  const request = useCallback(() => api.audit(robot, PAGE, 0), [robot]);
  const { page, error } = usePage(request, {
    what: "audit",
    enabled: allowed,
    refresh: newestAudited,
  });

  if (!allowed) return <p className="hint">Log in as an operator to see the audit log.</p>;
  const actions = [...new Set((page?.items ?? []).map((i) => i.action))].sort();
  const items = (page?.items ?? []).filter((i) => action === "" || i.action === action);
  return (
    <PagedTable
      filters={<FilterSelect label="action" testId="audit-action-filter" value={action} options={actions} onChange={setAction} />}
      source={page !== null ? `${page.total} in the log, newest ${PAGE} shown` : "loading…"}
      csv={{ testId: "audit-csv", href: auditCsvUrl(robot) }}
      error={error}
      label="Audit"
      testId="audit-table"
      columns={["time", "user", "client", "action", "fields", "before", "requested", "outcome", "reason"]}
      rows={items}
      row={(i) => (
        <tr key={i.id} data-action={i.action} data-outcome={i.outcome}>
          <td className="nowrap">{formatTimestamp(i.time)}</td>
          <td>{i.user ?? ""}</td>
          <td>{i.client ?? ""}</td>
          <td>{i.action}</td>
          <td title={short(i.fields)}>{pointsWords(i.fields, i.tags, i.labels)}</td>
          <td title={short(i.before)}>{values(i.before)}</td>
          <td title={short(i.requested)} data-testid="audit-summary">
            {i.summary ?? values(i.requested)}
          </td>
          <td>{i.outcome}</td>
          <td>{i.reason ?? ""}</td>
        </tr>
      )}
      empty="no entries"
    />
  );
});
