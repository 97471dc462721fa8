/** "Stale since …": stale data is never shown as live. */
import { formatMoment } from "../lib/common/dates";
import type { LiveSnapshot } from "../lib/stream/liveData";

export function StaleBanner({ live }: { readonly live: LiveSnapshot }) {
  if (live.health === "connected") return null;
  const since = live.staleSince_ms;
  const what = live.health === "stale" ? "Data is stale" : "Disconnected";
  return (
    <div className={`stale-banner stale-banner--${live.health}`} data-testid="stale-banner" role="alert">
      {what}
      {since !== null ? ` — stale since ${formatMoment(since, Date.now())}` : ""}
      {live.frame !== null ? "; the values shown are the last ones received." : "; no data received yet."}
    </div>
  );
}
