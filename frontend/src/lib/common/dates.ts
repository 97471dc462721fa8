/**
 * Layer: pure date formatting (no React, no DOM, no network).
 *
 * Every date and time on the pages is written one way: ISO 8601's order and the 24-hour clock,
 * "2026-11-27 07:21:04" (the date and the time separated by a space, as RFC 3339 allows),
 * ".737" added where milliseconds matter (the event, audit and alarm tables), the time alone,
 * "07:21:04", where the day is today. The time is the plant's: the zone the service names in the
 * stream's hello (its `time_zone` setting, docs/operations.md "Settings"; `setSiteTimeZone`), the
 * same the CSV exports and reports are written in, whatever zone the browser is set to; the
 * browser's own until the service has said. It is named once on each page (`timeZoneLabel`,
 * "Europe/Berlin, UTC+01:00") rather than after every time. Each function takes the zone as an
 * optional last argument (an IANA name), so the tests fix it.
 */

let browserZone: string | null = null;
let plantZone: string | null = null;

function browserTimeZone(): string {
  if (browserZone === null) {
    try {
      browserZone = Intl.DateTimeFormat().resolvedOptions().timeZone || "UTC";
    } catch {
      browserZone = "UTC";
    }
  }
  return browserZone;
}

/** The plant's time zone (an IANA name, "Europe/Berlin"): the service's, else the browser's. */
export function siteTimeZone(): string {
  return plantZone ?? browserTimeZone();
}

/**
 * The plant's zone as the service names it (the stream's hello); a name this browser does not
 * know is ignored (the browser's zone stays), null forgets it. True when it changed.
 */
export function setSiteTimeZone(zone: string | null | undefined): boolean {
  const next = zone === null || zone === undefined || zone === "" ? null : zone;
  if (next === plantZone) return false;
  if (next !== null) {
    try {
      new Intl.DateTimeFormat("en-US", { timeZone: next });
    } catch {
      return false;
    }
  }
  plantZone = next;
  return true;
}

interface Parts {
  readonly year: string;
  readonly month: string;
  readonly day: string;
  readonly hour: string;
  readonly minute: string;
  readonly second: string;
}

const formatters = new Map<string, Intl.DateTimeFormat>();

function formatterOf(zone: string): Intl.DateTimeFormat {
  let formatter = formatters.get(zone);
  if (formatter === undefined) {
    formatter = new Intl.DateTimeFormat("en-US", {
      timeZone: zone,
      hourCycle: "h23",
      year: "numeric",
      month: "2-digit",
      day: "2-digit",
      hour: "2-digit",
      minute: "2-digit",
      second: "2-digit",
    });
    formatters.set(zone, formatter);
  }
  return formatter;
}

/** The calendar fields of `epoch_ms` in `zone`, each zero-padded. */
function partsOf(epoch_ms: number, zone: string): Parts {
  const found: Record<string, string> = {};
  for (const part of formatterOf(zone).formatToParts(new Date(epoch_ms))) found[part.type] = part.value;
  const pad = (v: string | undefined, width = 2) => (v ?? "").padStart(width, "0");
  return {
    year: pad(found.year, 4),
    month: pad(found.month),
    day: pad(found.day),
    // Some engines write midnight as "24" even with h23.
    hour: found.hour === "24" ? "00" : pad(found.hour),
    minute: pad(found.minute),
    second: pad(found.second),
  };
}

function millis(epoch_ms: number): string {
  return String(Math.floor(((epoch_ms % 1000) + 1000) % 1000)).padStart(3, "0");
}

const valid = (epoch_ms: number) => Number.isFinite(epoch_ms);

/** "07:21:04": the time of day, for a moment of today (banners, the kiosk's clock). */
export function formatClock(epoch_ms: number, zone = siteTimeZone()): string {
  if (!valid(epoch_ms)) return "—";
  const p = partsOf(epoch_ms, zone);
  return `${p.hour}:${p.minute}:${p.second}`;
}

/** "2026-11-27 07:21:04" (`withMs`: "2026-11-27 07:21:04.737"). */
export function formatDateTime_ms(epoch_ms: number, withMs = false, zone = siteTimeZone()): string {
  if (!valid(epoch_ms)) return "—";
  const p = partsOf(epoch_ms, zone);
  return `${p.year}-${p.month}-${p.day} ${p.hour}:${p.minute}:${p.second}${withMs ? `.${millis(epoch_ms)}` : ""}`;
}

/** Tables' timestamps from the service's epoch seconds: "2026-11-27 07:21:04.737". */
export function formatTimestamp(epoch_s: number, zone = siteTimeZone()): string {
  return formatDateTime_ms(epoch_s * 1000, true, zone);
}

/**
 * A moment near `now_ms` as briefly as it stays clear: the time alone on the same day
 * ("07:21:04"), else the date too ("2026-11-26 23:58:10"), for "since …" and "until …".
 */
export function formatMoment(epoch_ms: number, now_ms: number, zone = siteTimeZone()): string {
  if (!valid(epoch_ms)) return "—";
  const p = partsOf(epoch_ms, zone);
  const today = partsOf(now_ms, zone);
  const sameDay = p.year === today.year && p.month === today.month && p.day === today.day;
  return sameDay ? formatClock(epoch_ms, zone) : formatDateTime_ms(epoch_ms, false, zone);
}

/** The offset of `zone` from UTC at `epoch_ms`, in minutes (east positive: Berlin in winter 60). */
export function utcOffset_min(epoch_ms: number, zone = siteTimeZone()): number {
  const p = partsOf(epoch_ms, zone);
  const asUtc = Date.UTC(Number(p.year), Number(p.month) - 1, Number(p.day), Number(p.hour), Number(p.minute), Number(p.second));
  return Math.round((asUtc - Math.floor(epoch_ms / 1000) * 1000) / 60_000);
}

/** "UTC+01:00", "UTC−03:30", "UTC+00:00". */
export function formatUtcOffset(offset_min: number): string {
  const sign = offset_min < 0 ? "\u2212" : "+";
  const abs = Math.abs(offset_min);
  return `UTC${sign}${String(Math.floor(abs / 60)).padStart(2, "0")}:${String(abs % 60).padStart(2, "0")}`;
}

/** The site's time zone as a page names it once: "Europe/Berlin, UTC+01:00" ("UTC" alone for UTC). */
export function timeZoneLabel(now_ms: number, zone = siteTimeZone()): string {
  const offset = formatUtcOffset(utcOffset_min(now_ms, zone));
  return zone === "UTC" || zone === "Etc/UTC" ? "UTC" : `${zone}, ${offset}`;
}

/**
 * What a plot's time axis is shifted by, ms (Plotly's date axis shows UTC): the plant's offset
 * with the sign of `Date.getTimezoneOffset` (Berlin in winter −3 600 000), so the axis reads the
 * plant's time.
 */
export function axisShift_ms(epoch_ms: number, zone = siteTimeZone()): number {
  return -utcOffset_min(epoch_ms, zone) * 60_000;
}

/** "2026-11-27T07:21:04": a `datetime-local` input's value for `epoch_ms`, in the plant's zone. */
export function formatInputDateTime(epoch_ms: number, zone = siteTimeZone()): string {
  return formatDateTime_ms(epoch_ms, false, zone).replace(" ", "T");
}

/**
 * A `datetime-local` input's value ("2026-11-27T07:21" or with seconds) read as the plant's wall
 * time: epoch ms, NaN when it is no such time.
 */
export function parseInputDateTime(text: string, zone = siteTimeZone()): number {
  const m = /^(\d{4})-(\d{2})-(\d{2})T(\d{2}):(\d{2})(?::(\d{2})(?:\.(\d{1,3}))?)?$/.exec(text.trim());
  if (m === null) return NaN;
  const [year, month, day, hour, minute, second = "0", ms = "0"] = m.slice(1);
  const wall = Date.UTC(Number(year), Number(month) - 1, Number(day), Number(hour), Number(minute), Number(second), Number(ms.padEnd(3, "0")));
  if (!Number.isFinite(wall)) return NaN;
  // The offset at the wall time read as UTC, then again at the moment found (a change of offset
  // between the two, around a daylight saving switch, is taken from the second).
  const first = wall - utcOffset_min(wall, zone) * 60_000;
  return wall - utcOffset_min(first, zone) * 60_000;
}
