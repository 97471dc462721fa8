// Scenario 41 (issue 38, "Evidence"), the plots' export: "Export the view" of a live plot on its
// 2 min window, opened seconds ago, covers the window its time axis shows (the front from the
// recording), not only the seconds that reached the page since it opened (a 2 min view gave 9 s
// of CSV); a range with nothing recorded says so on the plot and in the downloaded CSV. (The
// checkout's evidence and the interrupted cycles are in 34-checkout and 35-cycles.)
import type { Page } from "@playwright/test";
import { readFile } from "node:fs/promises";
import { expect, recorded, test } from "../support/fixtures";
import { settings } from "../support/settings";

const PLOT = "plot-joint-velocity";

/** Click the plot's CSV export and read the file: its lines. */
async function exportCsv(page: Page): Promise<string[]> {
  const downloading = page.waitForEvent("download");
  await page.getByTestId(`${PLOT}-export-csv`).click();
  const download = await downloading;
  return (await readFile((await download.path())!, "utf8")).trim().split(/\r?\n/);
}

/** The span of an export's rows (s): from its first frame's time to its last's. */
function spanOf(lines: readonly string[]): number {
  const times = lines
    .slice(1)
    .filter((l) => !l.startsWith("#"))
    .map((l) => Date.parse(l.split(",")[0]!.replace(/^"(.*)"$/, "$1")) / 1000);
  return times.length < 2 ? 0 : Math.max(...times) - Math.min(...times);
}

test("Export the view covers the 2 min window shown; a range with nothing recorded says so", async ({ page, request }) => {
  test.setTimeout(180_000);
  // The recording holds more than the page will: 40 s before the page opens.
  await expect
    .poll(async () => {
      const span = await recorded(request);
      return span.last - span.first;
    }, { timeout: 90_000, message: "40 s recorded" })
    .toBeGreaterThan(40);
  await page.goto(`/?robot=${settings.robotName}`);
  const plot = page.getByTestId(PLOT);
  await expect.poll(async () => Number(await plot.getAttribute("data-points"))).toBeGreaterThan(0);
  const opened_ms = Date.now();
  await page.getByTestId(`${PLOT}-window`).selectOption("120000");
  await expect(plot).toHaveAttribute("data-view", "ring");
  // Once the recording's answer drew the window's front, the export is the window shown: at
  // least 20 s more of frames than the page has held since it opened (the old export's all).
  let lines: string[] = [];
  const beyondThePage_s = async () => {
    lines = await exportCsv(page);
    return spanOf(lines) - (Date.now() - opened_ms) / 1000;
  };
  await expect.poll(beyondThePage_s, { timeout: 30_000 }).toBeGreaterThan(20);
  expect(lines.some((l) => l.startsWith("#"))).toBe(false);

  // A range before the cell existed: nothing recorded, said on the plot and in the file.
  await page.getByTestId(`${PLOT}-window`).selectOption("custom");
  await page.getByTestId(`${PLOT}-custom-from`).fill("2001-01-01T00:00:00");
  await page.getByTestId(`${PLOT}-custom-to`).fill("2001-01-01T00:10:00");
  await page.getByTestId(`${PLOT}-custom-apply`).click();
  await expect(plot).toHaveAttribute("data-view", "fixed");
  await expect(page.getByTestId(`${PLOT}-unrecorded`)).toHaveText(/^nothing recorded from 2001-01-01 00:00:00 to 2001-01-01 00:10:00$/);
  const empty = await exportCsv(page);
  expect(empty).toHaveLength(2);
  expect(empty[1]).toMatch(/^# nothing recorded from 200[01]-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{6}Z to 200[01]-/);
  await page.getByTestId(`${PLOT}-live`).click();
  await expect(plot).toHaveAttribute("data-view", "ring");
  await expect.poll(async () => (await page.getByTestId(`${PLOT}-unrecorded`).allTextContents()).join(" ")).not.toContain("2001");
});
