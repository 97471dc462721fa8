/**
 * The panel's paged tables (events, audit, alarm history) share their parts: a filter
 * (`FilterSelect`), a page asked for again when its request or a refresh changes (`usePage`,
 * the logic in `lib/history/paging.ts`), and the table itself with its bar (`PagedTable`: filters,
 * where the rows come from, the CSV export, the last error; an empty row when there is none).
 */
import { useEffect, useState, type ReactNode } from "react";
import { chosenOption, EMPTY_PAGE, optionValue, optionWords, pageAnswered, pageFailed, requestPageLater, type FilterOption, type PageAnswerLike, type PageOf, type PageState } from "../lib/history/paging";

/**
 * A table filter: one of `options`, or (unless `all` is null) the "all" entry, whose value is
 * the empty string. Only a value of the options (or "") reaches `onChange`.
 */
export function FilterSelect<T extends string>(props: {
  readonly label: string;
  readonly testId: string;
  readonly value: T | "";
  readonly options: readonly FilterOption<T>[];
  readonly onChange: (value: T | "") => void;
  /** The words of the "all" entry; null: no such entry (a choice is required). */
  readonly all?: string | null;
}) {
  const all = props.all === undefined ? "all" : props.all;
  return (
    <label>
      {props.label}{" "}
      <select data-testid={props.testId} value={props.value} onChange={(e) => props.onChange(chosenOption(props.options, e.target.value, ""))}>
        {all !== null && <option value="">{all}</option>}
        {props.options.map((option) => (
          <option key={optionValue(option)} value={optionValue(option)}>
            {optionWords(option)}
          </option>
        ))}
      </select>
    </label>
  );
}

/** A page, the last error, and the last answer that was not out of date (what it asked). */
export interface PageHook<P, A> extends PageState<P> {
  readonly answer: A | null;
}

/**
 * The page `request` answers, asked for (after a short quiet time) whenever `request` or
 * `refresh` changes; `request` must be memoized (`useCallback`) on what it asks. Not asked
 * while `enabled` is false (the page is then null; the last error stays).
 */
export function usePage<A extends PageAnswerLike<unknown>>(
  request: () => Promise<A>,
  options: { readonly what: string; readonly enabled?: boolean; readonly refresh?: unknown },
): PageHook<PageOf<A>, A> {
  const { what, enabled = true, refresh } = options;
  const [state, setState] = useState<PageHook<PageOf<A>, A>>({ ...EMPTY_PAGE, answer: null });
  useEffect(() => {
    if (!enabled) {
      setState((s) => ({ ...s, page: null }));
      return;
    }
    return requestPageLater(
      request,
      (answer) => setState((s) => ({ ...pageAnswered(s, answer as PageAnswerLike<PageOf<A>>, what), answer })),
      (error) => setState((s) => ({ ...pageFailed(s, error), answer: s.answer })),
    );
  }, [request, enabled, refresh, what]);
  return state;
}

/** A scrolling table under its bar: filters, the rows' source, the CSV link, the last error. */
export function PagedTable<T>(props: {
  /** The filters (`FilterSelect`s) at the start of the bar. */
  readonly filters: ReactNode;
  /** Where the rows come from, in words. */
  readonly source: string;
  readonly csv: { readonly href: string; readonly testId: string };
  readonly error: string | null;
  /** The scrolling region's accessible name. */
  readonly label: string;
  readonly testId: string;
  readonly columns: readonly string[];
  readonly rows: readonly T[];
  readonly row: (item: T) => ReactNode;
  /** The words of the one row shown when there are no rows. */
  readonly empty: string;
}) {
  return (
    <div className="table-view">
      <div className="table-view__bar">
        {props.filters}
        <span className="table-view__source">{props.source}</span>
        <a data-testid={props.csv.testId} href={props.csv.href} download>
          Export CSV
        </a>
        {props.error !== null && <span className="reason">{props.error}</span>}
      </div>
      <div className="table-scroll" tabIndex={0} role="region" aria-label={props.label}>
        <table data-testid={props.testId}>
          <thead>
            <tr>
              {props.columns.map((column) => (
                <th key={column}>{column}</th>
              ))}
            </tr>
          </thead>
          <tbody>
            {props.rows.map(props.row)}
            {props.rows.length === 0 && (
              <tr>
                <td colSpan={props.columns.length} className="empty">
                  {props.empty}
                </td>
              </tr>
            )}
          </tbody>
        </table>
      </div>
    </div>
  );
}
