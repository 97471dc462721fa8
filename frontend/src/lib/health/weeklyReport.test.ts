import { describe, expect, it } from "vitest";
import { lastWeek, reportCsvName, reportCsvUrl, reportTitle } from "./weeklyReport";

describe("the weekly health report", () => {
  it("covers the week ending now, as the CSV route's from and to", () => {
    const week = lastWeek(1_765_100_000_500);
    expect(week).toEqual({ from_s: 1_765_100_000 - 604_800, to_s: 1_765_100_000 });
    expect(reportCsvUrl("m1013", week)).toBe("/api/v1/robots/m1013/health/report.csv?from=1764495200&to=1765100000");
    expect(reportCsvName("m1013", week)).toBe("health-m1013-2025-12-07.csv");
  });

  it("is titled with its robot and its week in the site's time zone", () => {
    expect(reportTitle("m1013", { from_s: 1_764_495_200, to_s: 1_765_100_000 }, "UTC")).toBe("Weekly health report of m1013, 2025-11-30 09:33:20 – 2025-12-07 09:33:20");
  });
});
