/**
 * The I/O checkout (loop check) of the robot shown (docs/operations.md "I/O checkout"): start one,
 * or open one of the robot's checkouts; every point of the layout with its result. Inputs turn
 * "seen" by themselves when the robot's frames show them change (the view asks again every
 * second while the checkout is open); outputs are switched from here through the write
 * pipeline (control needed) and pass only once the robot confirmed them, every switch kept with
 * its confirmation time; a fail needs a comment. Several checkers may work at once on the
 * robot's one open checkout: while it is open, "Resume checkout N" takes its place of "Start a
 * checkout" (the service refuses a second). A closed checkout is read-only. The report: CSV, or this view printed (the
 * print stylesheet leaves the robot's identity, start and end, every point, who and when, and
 * the signature lines, without any button).
 */
import { memo, useCallback, useEffect, useMemo, useState } from "react";
import { ConfirmDialog } from "../components/ConfirmDialog";
import {
  checkoutApi,
  checkoutCsvUrl,
  countsWords,
  filterPoints,
  openCheckout,
  type Checkout,
  type CheckoutPoint,
  type CheckoutSummary,
  type PointFilter,
} from "../lib/commissioning/checkout";
import { formatTimestamp } from "../lib/common/dates";
import { roleAtLeast, type User } from "../lib/api/protocol";
import { CheckoutTable, type PointActions } from "./CheckoutTable";

const POLL_MS = 1000;
const FILTERS: readonly (readonly [PointFilter, string])[] = [
  ["all", "every point"],
  ["inputs", "inputs"],
  ["outputs", "outputs"],
  ["open", "without a verdict"],
  ["done", "seen or decided"],
];

function identityWords(checkout: Checkout): string {
  const id = checkout.identity;
  if (id === null) return "identity not read";
  return `${String(id.product_name ?? "")}, serial ${String(id.serial_number ?? "")}, revision ${String(id.revision ?? "")}`;
}

function ReportHeader({ checkout }: { readonly checkout: Checkout }) {
  return (
    <div className="checkout__header" data-testid="checkout-header">
      <h3>
        I/O checkout {checkout.id} of robot {checkout.robot}
      </h3>
      <p data-testid="checkout-identity">{identityWords(checkout)}</p>
      <p>
        Started {formatTimestamp(checkout.started_at)} by {checkout.started_by}
        {checkout.closed_at !== null
          ? `; closed ${formatTimestamp(checkout.closed_at)} by ${checkout.closed_by ?? ""}`
          : "; open"}
      </p>
      <p data-testid="checkout-counts">{countsWords(checkout.counts)}</p>
    </div>
  );
}

function Signatures() {
  return (
    <div className="checkout__signatures print-only" data-testid="checkout-signatures">
      <p>Checked by (name, signature, date): ______________________________________</p>
      <p>Approved by (name, signature, date): _____________________________________</p>
    </div>
  );
}

/** The browser's print of this view alone (styles/print.css keeps the other sections off). */
function printCheckout() {
  document.body.dataset.printSection = "checkout";
  try {
    window.print();
  } finally {
    delete document.body.dataset.printSection;
  }
}

function usePoll(robot: string, id: number | null, open: boolean, onCheckout: (c: Checkout) => void, onError: (e: string) => void) {
  useEffect(() => {
    if (id === null) return;
    let cancelled = false;
    const load = () => {
      checkoutApi
        .get(robot, id)
        .then((answer) => {
          if (cancelled) return;
          if (answer.ok) onCheckout(answer.page);
          else onError(answer.reason);
        })
        .catch((e: unknown) => !cancelled && onError(String(e)));
    };
    load();
    const timer = open ? window.setInterval(load, POLL_MS) : undefined;
    return () => {
      cancelled = true;
      if (timer !== undefined) window.clearInterval(timer);
    };
  }, [robot, id, open, onCheckout, onError]);
}

export const CheckoutView = memo(function CheckoutView({ robot, user }: { readonly robot: string; readonly user: User | null }) {
  const [list, setList] = useState<readonly CheckoutSummary[]>([]);
  const [chosen, setChosen] = useState<number | null>(null);
  const [checkout, setCheckout] = useState<Checkout | null>(null);
  const [filter, setFilter] = useState<PointFilter>("all");
  const [text, setText] = useState("");
  const [error, setError] = useState<string | null>(null);
  const [busy, setBusy] = useState(false);
  const [closing, setClosing] = useState(false);
  const [reload, setReload] = useState(0);
  const operator = roleAtLeast(user, "operator");

  useEffect(() => {
    let cancelled = false;
    checkoutApi
      .list(robot)
      .then((answer) => {
        if (cancelled) return;
        if (answer.ok) {
          setList(answer.page.items);
          setChosen((now) => now ?? answer.page.items.find((c) => c.closed_at === null)?.id ?? null);
        } else setError(answer.reason);
      })
      .catch((e: unknown) => !cancelled && setError(String(e)));
    return () => {
      cancelled = true;
    };
  }, [robot, reload, user]);

  // Another robot: its own checkouts.
  useEffect(() => {
    setChosen(null);
    setCheckout(null);
  }, [robot]);

  const shown = checkout !== null && checkout.id === chosen ? checkout : null;
  const open = shown !== null && shown.closed_at === null;
  usePoll(robot, chosen, open || shown === null, setCheckout, setError);

  const points = useMemo(() => (shown === null ? [] : filterPoints(shown.points, filter, text)), [shown, filter, text]);
  const resumable = openCheckout(list);

  const act = useCallback(
    async (action: () => Promise<{ ok: true; page: CheckoutPoint } | { ok: false; reason: string }>) => {
      setBusy(true);
      try {
        const answer = await action();
        if (answer.ok) {
          setError(null);
          setCheckout((c) => (c === null ? c : { ...c, points: c.points.map((p) => (p.key === answer.page.key ? answer.page : p)) }));
        } else setError(answer.reason);
      } catch (e) {
        setError(String(e));
      } finally {
        setBusy(false);
      }
    },
    [],
  );

  const actions = useMemo<PointActions | null>(() => {
    if (chosen === null) return null;
    return {
      switchOutput: (p, value) => void act(() => checkoutApi.switchOutput(robot, chosen, p.key, value)),
      capture: (p) => void act(() => checkoutApi.capture(robot, chosen, p.key)),
      record: (p, result, comment) => void act(() => checkoutApi.record(robot, chosen, p.key, result, comment)),
    };
  }, [act, robot, chosen]);

  const start = async () => {
    setBusy(true);
    try {
      const answer = await checkoutApi.start(robot);
      if (answer.ok) {
        setCheckout(answer.page);
        setChosen(answer.page.id);
        setError(null);
        setReload((n) => n + 1);
      } else {
        setError(answer.reason);
        // Another checker started one meanwhile (409): the list offers it to resume.
        setReload((n) => n + 1);
      }
    } finally {
      setBusy(false);
    }
  };

  const close = async (ok: boolean) => {
    setClosing(false);
    if (!ok || chosen === null) return;
    const answer = await checkoutApi.close(robot, chosen);
    if (answer.ok) {
      setCheckout(answer.page);
      setReload((n) => n + 1);
    } else setError(answer.reason);
  };

  return (
    <div className="table-view checkout" data-testid="checkout-view">
      <div className="table-view__bar no-print">
        <label>
          checkout{" "}
          <select
            data-testid="checkout-choose"
            value={chosen ?? ""}
            onChange={(e) => setChosen(e.target.value === "" ? null : Number(e.target.value))}
          >
            <option value="">—</option>
            {list.map((c) => (
              <option key={c.id} value={c.id}>
                {c.id}: {formatTimestamp(c.started_at)} {c.closed_at === null ? "(open)" : "(closed)"}
              </option>
            ))}
          </select>
        </label>
        {operator && resumable === null && (
          <button type="button" className="primary" data-testid="checkout-start" disabled={busy} onClick={() => void start()}>
            Start a checkout
          </button>
        )}
        {resumable !== null && resumable.id !== chosen && (
          <button type="button" className="primary" data-testid="checkout-resume" onClick={() => setChosen(resumable.id)}>
            Resume checkout {resumable.id}
          </button>
        )}
        {shown !== null && (
          <>
            <label>
              show{" "}
              <select data-testid="checkout-filter" value={filter} onChange={(e) => setFilter(e.target.value as PointFilter)}>
                {FILTERS.map(([value, words]) => (
                  <option key={value} value={value}>
                    {words}
                  </option>
                ))}
              </select>
            </label>
            <label>
              find <input data-testid="checkout-find" value={text} placeholder="DI 5, register, gripper…" onChange={(e) => setText(e.target.value)} />
            </label>
            <a data-testid="checkout-csv" href={checkoutCsvUrl(robot, shown.id)} download={`${robot}-checkout-${shown.id}.csv`}>
              Report CSV
            </a>
            <button type="button" data-testid="checkout-print" onClick={printCheckout}>
              Print
            </button>
            {open && operator && (
              <button type="button" data-testid="checkout-close" disabled={busy} onClick={() => setClosing(true)}>
                Close checkout
              </button>
            )}
          </>
        )}
        {error !== null && (
          <span className="reason" role="alert" data-testid="checkout-error">
            {error}
          </span>
        )}
      </div>
      {shown === null ? (
        <p className="hint">{list.length === 0 ? "No checkout of this robot yet." : "Choose a checkout."}</p>
      ) : (
        <>
          <ReportHeader checkout={shown} />
          {open && <p className="hint no-print">Inputs turn “seen” when the robot reports them changing; switching an output needs control.</p>}
          {actions !== null && <CheckoutTable points={points} open={open && operator} busy={busy} actions={actions} />}
          <Signatures />
        </>
      )}
      {closing && (
        <ConfirmDialog
          message={`Close checkout ${chosen ?? ""}? It becomes read-only.`}
          confirmLabel="Close it"
          onAnswer={(ok) => void close(ok)}
        />
      )}
    </div>
  );
});
