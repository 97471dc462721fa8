/**
 * The logic of the panel's paged tables (events, audit, alarm history), without React: a
 * filter's choice read back from a `<select>`, and a page asked for after a short quiet time
 * (filters change in bursts, events arrive in bursts), whose answer is dropped once a newer
 * request replaced it. `components/PagedTable.tsx` is the React side.
 */

/** What a page request answers (`lib/api/api.ts`'s `PageAnswer`, the alarms API's too). */
export type PageAnswerLike<P> = { readonly ok: true; readonly page: P } | { readonly ok: false; readonly reason: string };

/** The page type of an answer type. */
export type PageOf<A> = A extends { readonly ok: true; readonly page: infer P } ? P : never;

/** A table's page and the last error; an error keeps the page shown before it. */
export interface PageState<P> {
  readonly page: P | null;
  readonly error: string | null;
}

export const EMPTY_PAGE: PageState<never> = { page: null, error: null };

/** Quiet time before a page is asked for, ms. */
export const PAGE_FETCH_DELAY_MS = 300;

/** A filter's option: its value, or its value and the words shown for it. */
export type FilterOption<T extends string> = T | readonly [T, string];

export function optionValue<T extends string>(option: FilterOption<T>): T {
  return typeof option === "string" ? option : option[0];
}

export function optionWords<T extends string>(option: FilterOption<T>): string {
  return typeof option === "string" ? option : option[1];
}

/**
 * The option a `<select>` says was chosen, or `fallback` for anything else (the "all" entry's
 * empty value, or a value no option has).
 */
export function chosenOption<T extends string, F extends string>(options: readonly FilterOption<T>[], raw: string, fallback: F): T | F {
  for (const option of options) {
    const value = optionValue(option);
    if (value === raw) return value;
  }
  return fallback;
}

/** The state after an answer (`what` names the table in an error: "events: …"). */
export function pageAnswered<P>(state: PageState<P>, answer: PageAnswerLike<P>, what: string): PageState<P> {
  return answer.ok ? { page: answer.page, error: null } : { page: state.page, error: `${what}: ${answer.reason}` };
}

/** The state after a request failed outright (the network, a bug): the error as it came. */
export function pageFailed<P>(state: PageState<P>, error: unknown): PageState<P> {
  return { page: state.page, error: String(error) };
}

/**
 * Ask `request` after `delayMs`, hand its answer (or its failure) to `onAnswer` / `onFailure`;
 * the function that cancels it: not asked if still waiting, its answer dropped if under way.
 */
export function requestPageLater<A>(
  request: () => Promise<A>,
  onAnswer: (answer: A) => void,
  onFailure: (error: unknown) => void,
  delayMs: number = PAGE_FETCH_DELAY_MS,
): () => void {
  let cancelled = false;
  const timer = setTimeout(() => {
    request()
      .then((answer) => {
        if (!cancelled) onAnswer(answer);
      })
      .catch((error: unknown) => {
        if (!cancelled) onFailure(error);
      });
  }, delayMs);
  return () => {
    cancelled = true;
    clearTimeout(timer);
  };
}
