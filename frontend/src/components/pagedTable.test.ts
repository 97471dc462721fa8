// The shared table parts as markup (react-dom/server, no DOM): the filter's entries and test id,
// the bar (source, CSV link, error) and the table (columns, rows, the one empty row) with the
// data attributes and names the end-to-end tests and axe read.
import { createElement } from "react";
import { renderToStaticMarkup } from "react-dom/server";
import { describe, expect, it } from "vitest";
import { FilterSelect, PagedTable } from "./PagedTable";

describe("FilterSelect", () => {
  it("offers all, then each option, the value chosen selected", () => {
    const html = renderToStaticMarkup(
      createElement(FilterSelect<"write" | "control">, { label: "action", testId: "audit-action-filter", value: "control", options: ["write", "control"], onChange: () => undefined }),
    );
    expect(html).toBe(
      '<label>action <select data-testid="audit-action-filter"><option value="">all</option><option value="write">write</option><option value="control" selected="">control</option></select></label>',
    );
  });

  it("shows an option's words, and no all entry when a choice is required", () => {
    const html = renderToStaticMarkup(
      createElement(FilterSelect<"hour" | "day">, {
        label: "period",
        testId: "alarm-history-period",
        value: "day",
        options: [
          ["hour", "last hour"],
          ["day", "last 24 h"],
        ],
        all: null,
        onChange: () => undefined,
      }),
    );
    expect(html).not.toContain('value=""');
    expect(html).toContain('<option value="hour">last hour</option><option value="day" selected="">last 24 h</option>');
  });
});

describe("PagedTable", () => {
  const props = {
    filters: createElement("span", { id: "filters" }),
    source: "3 in the log",
    csv: { href: "/api/v1/events?format=csv", testId: "events-csv" },
    label: "Events",
    testId: "events-table",
    columns: ["time", "kind", "what"],
    row: (item: string) => createElement("tr", { key: item, "data-kind": item }, createElement("td", null, item)),
    empty: "no events",
  };

  it("has the bar and a row per item", () => {
    const html = renderToStaticMarkup(createElement(PagedTable<string>, { ...props, error: null, rows: ["flag", "write"] }));
    expect(html).toContain('<div class="table-view"><div class="table-view__bar"><span id="filters"></span><span class="table-view__source">3 in the log</span>');
    expect(html).toContain('<a data-testid="events-csv" href="/api/v1/events?format=csv" download="">Export CSV</a>');
    expect(html).not.toContain('class="reason"');
    expect(html).toContain('<div class="table-scroll" tabindex="0" role="region" aria-label="Events"><table data-testid="events-table">');
    expect(html).toContain("<thead><tr><th>time</th><th>kind</th><th>what</th></tr></thead>");
    expect(html).toContain('<tbody><tr data-kind="flag"><td>flag</td></tr><tr data-kind="write"><td>write</td></tr></tbody>');
    expect(html).not.toContain("no events");
  });

  it("shows the error, and one empty row across every column", () => {
    const html = renderToStaticMarkup(createElement(PagedTable<string>, { ...props, error: "events: 500", rows: [] }));
    expect(html).toContain('<span class="reason">events: 500</span>');
    expect(html).toContain('<tbody><tr><td colSpan="3" class="empty">no events</td></tr></tbody>');
  });
});
