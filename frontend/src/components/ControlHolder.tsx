/** Who holds control of the outputs (read-only view). */
import { formatClock } from "../lib/health";
import type { ControlStatus } from "../lib/protocol";

export function ControlHolder({ control }: { readonly control: ControlStatus }) {
  const holder = control.holder;
  return (
    <div className="control-holder" data-testid="control-holder" data-holder={holder?.user ?? ""}>
      <span className="control-holder__label">control</span>{" "}
      {holder === null ? (
        <span className="control-holder__nobody">nobody</span>
      ) : (
        <span>
          <strong>{holder.user}</strong> since {formatClock(holder.since * 1000)}
        </span>
      )}
    </div>
  );
}
