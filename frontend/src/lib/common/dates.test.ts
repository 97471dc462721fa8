import { describe, expect, it } from "vitest";
import {
  axisShift_ms,
  formatClock,
  formatDateTime_ms,
  formatInputDateTime,
  formatMoment,
  formatTimestamp,
  formatUtcOffset,
  parseInputDateTime,
  setSiteTimeZone,
  siteTimeZone,
  timeZoneLabel,
  utcOffset_min,
} from "./dates";

// 2026-11-27 06:21:04.737 UTC (winter: Berlin is UTC+01:00, New York UTC−05:00).
const WINTER_MS = Date.UTC(2026, 10, 27, 6, 21, 4, 737);
// 2026-07-01 12:00:00 UTC (summer: Berlin UTC+02:00).
const SUMMER_MS = Date.UTC(2026, 6, 1, 12, 0, 0);

describe("one date format", () => {
  it("writes date and time in ISO 8601's order with the 24-hour clock, in the site's zone", () => {
    expect(formatDateTime_ms(WINTER_MS, false, "UTC")).toBe("2026-11-27 06:21:04");
    expect(formatDateTime_ms(WINTER_MS, false, "Europe/Berlin")).toBe("2026-11-27 07:21:04");
    expect(formatDateTime_ms(WINTER_MS, true, "Europe/Berlin")).toBe("2026-11-27 07:21:04.737");
    expect(formatDateTime_ms(SUMMER_MS, false, "Europe/Berlin")).toBe("2026-07-01 14:00:00");
    // The afternoon is 24 h, never AM/PM.
    expect(formatClock(Date.UTC(2026, 10, 27, 19, 5, 9), "UTC")).toBe("19:05:09");
    expect(formatClock(Date.UTC(2026, 10, 27, 0, 0, 0), "UTC")).toBe("00:00:00");
  });

  it("takes the service's epoch seconds in the tables, to the millisecond", () => {
    expect(formatTimestamp(WINTER_MS / 1000, "America/New_York")).toBe("2026-11-27 01:21:04.737");
    expect(formatTimestamp(0, "UTC")).toBe("1970-01-01 00:00:00.000");
  });

  it("gives a moment of today as its time alone and another day's with its date", () => {
    const now = Date.UTC(2026, 10, 27, 12, 0, 0);
    expect(formatMoment(WINTER_MS, now, "UTC")).toBe("06:21:04");
    expect(formatMoment(WINTER_MS - 24 * 3600_000, now, "UTC")).toBe("2026-11-26 06:21:04");
    // Today in Berlin is not today in Tokyo.
    expect(formatMoment(Date.UTC(2026, 10, 27, 16, 0, 0), now, "Asia/Tokyo")).toBe("2026-11-28 01:00:00");
  });

  it("names the zone once with its offset from UTC", () => {
    expect(utcOffset_min(WINTER_MS, "Europe/Berlin")).toBe(60);
    expect(utcOffset_min(SUMMER_MS, "Europe/Berlin")).toBe(120);
    expect(utcOffset_min(WINTER_MS, "America/St_Johns")).toBe(-210);
    expect(formatUtcOffset(-210)).toBe("UTC\u221203:30");
    expect(formatUtcOffset(0)).toBe("UTC+00:00");
    expect(timeZoneLabel(WINTER_MS, "Europe/Berlin")).toBe("Europe/Berlin, UTC+01:00");
    expect(timeZoneLabel(WINTER_MS, "UTC")).toBe("UTC");
  });

  it("writes a dash for a time that is not one", () => {
    expect(formatClock(NaN, "UTC")).toBe("—");
    expect(formatDateTime_ms(Infinity, true, "UTC")).toBe("—");
  });
});

describe("the plant's time zone (issue 38 item 9)", () => {
  it("is the one the service names, whatever zone the browser is in; an unknown name is ignored", () => {
    const browser = siteTimeZone();
    try {
      expect(setSiteTimeZone("Asia/Tokyo")).toBe(true);
      expect(siteTimeZone()).toBe("Asia/Tokyo");
      // Every format follows: the tables, the clock, the zone's name on the page.
      expect(formatTimestamp(WINTER_MS / 1000)).toBe("2026-11-27 15:21:04.737");
      expect(formatClock(WINTER_MS)).toBe("15:21:04");
      expect(timeZoneLabel(WINTER_MS)).toBe("Asia/Tokyo, UTC+09:00");
      expect(setSiteTimeZone("Mars/Olympus_Mons")).toBe(false);
      expect(siteTimeZone()).toBe("Asia/Tokyo");
      expect(setSiteTimeZone("Asia/Tokyo")).toBe(false); // no change
    } finally {
      setSiteTimeZone(null);
    }
    expect(siteTimeZone()).toBe(browser);
  });

  it("shifts the plots' time axis by the plant's offset, summer and winter", () => {
    // With the sign of Date.getTimezoneOffset: Berlin is east of UTC.
    expect(axisShift_ms(WINTER_MS, "Europe/Berlin")).toBe(-3_600_000);
    expect(axisShift_ms(SUMMER_MS, "Europe/Berlin")).toBe(-7_200_000);
    expect(axisShift_ms(WINTER_MS, "America/New_York")).toBe(5 * 3_600_000);
  });

  it("reads and writes a custom range's inputs in the plant's time", () => {
    expect(formatInputDateTime(WINTER_MS, "Europe/Berlin")).toBe("2026-11-27T07:21:04");
    expect(parseInputDateTime("2026-11-27T07:21:04", "Europe/Berlin")).toBe(Math.floor(WINTER_MS / 1000) * 1000);
    expect(parseInputDateTime("2026-07-01T14:00", "Europe/Berlin")).toBe(SUMMER_MS);
    expect(parseInputDateTime("2026-11-27T01:21:04.737", "America/New_York")).toBe(WINTER_MS);
    expect(parseInputDateTime("yesterday", "UTC")).toBeNaN();
  });
});
