// The paged tables' logic (events, audit, alarm history): a filter's choice read back, the page
// state after answers and failures, and a request asked for after a quiet time whose answer is
// dropped once cancelled.
import { afterEach, beforeEach, describe, expect, it, vi } from "vitest";
import { chosenOption, EMPTY_PAGE, optionValue, optionWords, PAGE_FETCH_DELAY_MS, pageAnswered, pageFailed, requestPageLater, type PageAnswerLike, type PageState } from "./paging";

describe("filter options", () => {
  const periods = [
    ["hour", "last hour"],
    ["day", "last 24 h"],
  ] as const;

  it("reads a value or a value with its words", () => {
    expect(optionValue("critical")).toBe("critical");
    expect(optionWords("critical")).toBe("critical");
    expect(optionValue(periods[1])).toBe("day");
    expect(optionWords(periods[1])).toBe("last 24 h");
  });

  it("takes only a value of the options, else the fallback", () => {
    expect(chosenOption(["write", "control"], "control", "")).toBe("control");
    expect(chosenOption(["write", "control"], "", "")).toBe("");
    expect(chosenOption(["write", "control"], "alarm", "")).toBe("");
    expect(chosenOption(periods, "hour", "")).toBe("hour");
    expect(chosenOption(periods, "last hour", "")).toBe(""); // the words are not the value
    expect(chosenOption([], "x", "none")).toBe("none");
  });
});

describe("page state", () => {
  const shown: PageState<string> = { page: "page 1", error: null };

  it("shows an answered page and clears the error", () => {
    const failed: PageState<string> = { page: "page 1", error: "events: 500" };
    expect(pageAnswered(failed, { ok: true, page: "page 2" }, "events")).toEqual({ page: "page 2", error: null });
  });

  it("keeps the page shown on a refusal or a failure, naming the table", () => {
    expect(pageAnswered(shown, { ok: false, reason: "login required" }, "audit")).toEqual({ page: "page 1", error: "audit: login required" });
    expect(pageFailed(shown, new TypeError("Failed to fetch"))).toEqual({ page: "page 1", error: "TypeError: Failed to fetch" });
    expect(pageFailed(EMPTY_PAGE, "offline")).toEqual({ page: null, error: "offline" });
  });
});

describe("requestPageLater", () => {
  beforeEach(() => {
    vi.useFakeTimers();
  });
  afterEach(() => {
    vi.useRealTimers();
  });

  function deferred<T>() {
    let resolve!: (value: T) => void;
    let reject!: (error: unknown) => void;
    const promise = new Promise<T>((yes, no) => {
      resolve = yes;
      reject = no;
    });
    return { promise, resolve, reject };
  }

  it("asks after the quiet time and hands the answer on", async () => {
    const answer: PageAnswerLike<string> = { ok: true, page: "p" };
    const request = vi.fn(() => Promise.resolve(answer));
    const onAnswer = vi.fn();
    const onFailure = vi.fn();
    requestPageLater(request, onAnswer, onFailure);
    await vi.advanceTimersByTimeAsync(PAGE_FETCH_DELAY_MS - 1);
    expect(request).not.toHaveBeenCalled();
    await vi.advanceTimersByTimeAsync(1);
    expect(request).toHaveBeenCalledTimes(1);
    expect(onAnswer).toHaveBeenCalledWith(answer);
    expect(onFailure).not.toHaveBeenCalled();
  });

  it("asks nothing when cancelled during the quiet time (a burst of changes asks once)", async () => {
    const request = vi.fn(() => Promise.resolve({ ok: true as const, page: 1 }));
    const onAnswer = vi.fn();
    for (let i = 0; i < 5; i++) {
      const cancel = requestPageLater(request, onAnswer, () => undefined);
      await vi.advanceTimersByTimeAsync(PAGE_FETCH_DELAY_MS / 2);
      cancel();
    }
    requestPageLater(request, onAnswer, () => undefined);
    await vi.advanceTimersByTimeAsync(PAGE_FETCH_DELAY_MS);
    expect(request).toHaveBeenCalledTimes(1);
    expect(onAnswer).toHaveBeenCalledTimes(1);
  });

  it("drops the answer or the failure of a request cancelled under way", async () => {
    const slow = deferred<PageAnswerLike<number>>();
    const onAnswer = vi.fn();
    const cancel = requestPageLater(() => slow.promise, onAnswer, () => undefined);
    await vi.advanceTimersByTimeAsync(PAGE_FETCH_DELAY_MS);
    cancel();
    slow.resolve({ ok: true, page: 1 });
    await vi.runAllTimersAsync();
    expect(onAnswer).not.toHaveBeenCalled();

    const failing = deferred<PageAnswerLike<number>>();
    const onFailure = vi.fn();
    const cancelToo = requestPageLater(() => failing.promise, () => undefined, onFailure);
    await vi.advanceTimersByTimeAsync(PAGE_FETCH_DELAY_MS);
    cancelToo();
    failing.reject(new Error("network"));
    await vi.runAllTimersAsync();
    expect(onFailure).not.toHaveBeenCalled();
  });

  it("reports a failed request", async () => {
    const onFailure = vi.fn();
    requestPageLater(() => Promise.reject(new Error("network")), () => undefined, onFailure, 10);
    await vi.advanceTimersByTimeAsync(10);
    expect(onFailure).toHaveBeenCalledWith(new Error("network"));
  });
});
