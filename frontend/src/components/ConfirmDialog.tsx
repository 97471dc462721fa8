/**
 * A modal confirmation: Escape cancels, Enter confirms (Enter on the Cancel button cancels),
 * Tab and Shift+Tab stay inside, focus goes back where it was when the dialog closes. An
 * optional warning (e.g. the robot is in an emergency stop) is shown above the buttons.
 */
import { useEffect, useRef } from "react";

interface Props {
  readonly message: string;
  readonly warning?: string | null;
  readonly confirmLabel?: string;
  readonly onAnswer: (ok: boolean) => void;
}

const FOCUSABLE = 'button:not([disabled]), [href], input:not([disabled]), select:not([disabled]), textarea:not([disabled]), [tabindex]:not([tabindex="-1"])';

export function ConfirmDialog({ message, warning = null, confirmLabel = "Confirm", onAnswer }: Props) {
  const dialog = useRef<HTMLDivElement | null>(null);
  const confirm = useRef<HTMLButtonElement | null>(null);
  const answer = useRef(onAnswer);
  useEffect(() => {
    answer.current = onAnswer;
  }, [onAnswer]);

  useEffect(() => {
    const before = document.activeElement instanceof HTMLElement ? document.activeElement : null;
    confirm.current?.focus();
    const onKey = (e: KeyboardEvent) => {
      const box = dialog.current;
      if (box === null) return;
      if (e.key === "Escape") {
        e.preventDefault();
        e.stopPropagation();
        answer.current(false);
        return;
      }
      if (e.key === "Enter") {
        // A focused button answers with its own click.
        if (e.target instanceof HTMLButtonElement && box.contains(e.target)) return;
        e.preventDefault();
        answer.current(true);
        return;
      }
      if (e.key === "Tab") {
        const items = Array.from(box.querySelectorAll<HTMLElement>(FOCUSABLE));
        const first = items[0];
        const last = items[items.length - 1];
        if (first === undefined || last === undefined) return;
        const inside = document.activeElement instanceof Node && box.contains(document.activeElement);
        if (e.shiftKey && (document.activeElement === first || !inside)) {
          e.preventDefault();
          last.focus();
        } else if (!e.shiftKey && (document.activeElement === last || !inside)) {
          e.preventDefault();
          first.focus();
        }
      }
    };
    document.addEventListener("keydown", onKey, true);
    return () => {
      document.removeEventListener("keydown", onKey, true);
      if (before !== null && before.isConnected) before.focus();
    };
  }, []);

  return (
    <div className="dialog-backdrop">
      <div
        className="dialog"
        role="alertdialog"
        aria-modal="true"
        aria-labelledby="confirm-text"
        aria-describedby={warning !== null ? "confirm-warning" : undefined}
        data-testid="confirm-dialog"
        ref={dialog}
      >
        <p id="confirm-text">{message}</p>
        {warning !== null && (
          <p id="confirm-warning" className="dialog__warning" data-testid="confirm-warning" role="alert">
            {warning}
          </p>
        )}
        <div className="dialog__buttons">
          <button type="button" data-testid="confirm-no" onClick={() => onAnswer(false)}>
            Cancel
          </button>
          <button type="button" className="primary" data-testid="confirm-yes" ref={confirm} onClick={() => onAnswer(true)}>
            {confirmLabel}
          </button>
        </div>
      </div>
    </div>
  );
}
