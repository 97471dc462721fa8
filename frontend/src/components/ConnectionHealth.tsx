/** Connection health: connected / stale / disconnected, frame age, measured interval, gaps. */
import { formatDuration_ms, packetLossOf } from "../lib/stream/health";
import type { LiveSnapshot } from "../lib/stream/liveData";

interface Props {
  readonly live: LiveSnapshot;
  readonly compact?: boolean;
}

function fixed(v: number | null | undefined, digits: number): string {
  return v === null || v === undefined || !Number.isFinite(v) ? "—" : v.toFixed(digits);
}

export function ConnectionHealth({ live, compact = false }: Props) {
  const c = live.connection;
  const reason =
    live.socket !== "open"
      ? (live.closeReason ??
        (live.socket === "connecting" ? "connecting to the HMI service…" : "no connection to the HMI service"))
      : c !== null && c.state !== "connected"
        ? `robot link ${c.state}${c.reason !== null ? `: ${c.reason}` : ""}`
        : null;
  // The service's packet-loss alarm (gaps per minute over its threshold) turns a live badge amber.
  const { high: lossy, words: lossWords } = packetLossOf(live.health, c);
  return (
    <div className={`health health--${live.health}${lossy ? " health--amber" : ""}`} aria-label="Connection health">
      <div
        className="health__status"
        data-testid="connection-status"
        data-state={live.health}
        data-packet-loss={lossy ? "high" : "normal"}
        title={reason ?? lossWords ?? ""}
      >
        <span className="health__dot" aria-hidden="true" />
        {live.health}
        {lossy && <span className="health__loss"> · packet loss</span>}
      </div>
      <dl className="health__figures">
        <div>
          <dt>frame age</dt>
          <dd className="health__age" data-testid="frame-age" data-age-ms={live.frameAge_ms === null ? "" : Math.round(live.frameAge_ms)}>
            {formatDuration_ms(live.frameAge_ms)}
          </dd>
        </div>
        <div>
          <dt>interval</dt>
          <dd data-testid="frame-interval" title={`p99 ${fixed(c?.interval_p99_ms, 1)} ms, max ${fixed(c?.interval_max_ms, 1)} ms`}>
            {fixed(c?.interval_mean_ms, 1)} ms{c !== null ? ` / RPI ${fixed(c.rpi_ms, 0)} ms` : ""}
          </dd>
        </div>
        <div>
          <dt>gaps</dt>
          <dd
            data-testid="frame-gaps"
            data-gaps={c?.gaps ?? 0}
            title={`robot link gaps ${c?.gaps ?? "—"}; missed by this browser ${live.clientGaps}; dropped for this browser ${live.dropped}`}
          >
            {c?.gaps ?? "—"}
            {live.clientGaps + live.dropped > 0 ? ` (+${live.clientGaps + live.dropped} here)` : ""}
          </dd>
        </div>
        {!compact && c !== null && (
          <div>
            <dt>robot</dt>
            <dd data-testid="robot-address">
              {c.robot}
              {c.mode === "input_only" ? " · read-only (input only)" : ""}
            </dd>
          </div>
        )}
      </dl>
      {reason !== null && (
        <div className="health__reason" data-testid="connection-reason">
          {reason}
        </div>
      )}
    </div>
  );
}
