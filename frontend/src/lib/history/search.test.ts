import { describe, expect, it } from "vitest";
import { NO_SEARCH, isSearching, pageWords, searchEventsCsvUrl, searchQuery } from "./search";

describe("searching the logs", () => {
  it("asks only for what was given, the text trimmed", () => {
    expect(searchQuery(NO_SEARCH)).toEqual({});
    expect(isSearching(NO_SEARCH)).toBe(false);
    expect(searchQuery({ text: "  e-stop ", from: "2026-11-27T12:00", to: "" })).toEqual({ q: "e-stop", from: "2026-11-27T12:00" });
    expect(isSearching({ text: " ", from: "", to: "2026-11-27T13:00" })).toBe(true);
  });

  it("links the CSV of the search", () => {
    const url = searchEventsCsvUrl("r1", "alarm", { text: "100%", from: "", to: "2026-11-27T13:00" });
    const query = new URLSearchParams(url.split("?")[1]);
    expect(url.startsWith("/api/v1/events?")).toBe(true);
    expect(Object.fromEntries(query)).toEqual({ robot: "r1", format: "csv", limit: "100000", q: "100%", to: "2026-11-27T13:00", kind: "alarm" });
  });

  it("says which rows a page shows", () => {
    expect(pageWords(40, 20, 75)).toBe("41–60 of 75");
    expect(pageWords(0, 0, 0)).toBe("0 of 0");
  });
});
