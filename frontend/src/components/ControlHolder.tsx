/** Who holds control of the outputs (read-only view). */
import type { Ownership } from "../lib/writes/controlSession";
import { formatMoment } from "../lib/common/dates";
import type { ControlStatus } from "../lib/api/protocol";

/**
 * `ownership` (the panel's, lib/writes/controlSession.ts) says whether it is this window's control or
 * the same user's in another window; the kiosk, which has no user, leaves it out.
 */
export function ControlHolder({ control, ownership }: { readonly control: ControlStatus; readonly ownership?: Ownership }) {
  const holder = control.holder;
  return (
    <div
      className="control-holder"
      data-testid="control-holder"
      data-holder={holder?.user ?? ""}
      data-ownership={ownership ?? ""}
    >
      <span className="control-holder__label">control</span>{" "}
      {holder === null ? (
        <span className="control-holder__nobody">nobody</span>
      ) : (
        <span>
          <strong>{holder.user}</strong>
          {ownership === "you" && " (you)"}
          {ownership === "you-elsewhere" && (
            <span className="control-holder__elsewhere" data-testid="control-elsewhere">
              {" "}
              — held by you in another window
            </span>
          )}{" "}
          since {formatMoment(holder.since * 1000, Date.now())}
        </span>
      )}
    </div>
  );
}
