/**
 * The commissioning panel (`/`): state, flags, connection health and control always visible in
 * a sticky header; live joint and TCP plots; I/O and registers with writes; events and audit.
 */
import { useCallback, useEffect, useMemo, useState } from "react";
import { ConnectionHealth } from "../components/ConnectionHealth";
import { ControlHolder } from "../components/ControlHolder";
import { FlagBadges } from "../components/FlagBadges";
import { LivePlotView } from "../components/LivePlotView";
import { RuntimeContext, useLive } from "../components/runtimeContext";
import { StaleBanner } from "../components/StaleBanner";
import { StateBadge } from "../components/StateBadge";
import { getMe } from "../lib/api";
import { ALL_PLOTS, JOINT_PLOTS, TCP_PLOTS } from "../lib/plots";
import type { ControlStatus, User } from "../lib/protocol";
import { createLiveRuntime, type LiveRuntime } from "../lib/runtime";
import { AuditView, EventsView } from "./EventsView";
import { IoSection } from "./IoSection";
import { RegistersSection } from "./RegistersSection";
import { SessionBar } from "./SessionBar";
import { WriteProvider, useWrites } from "./writeContext";
import "../styles/panel.css";

declare global {
  interface Window {
    /** The live pipeline, for the UI benchmark and debugging in the console. */
    __cobotHmi?: LiveRuntime;
  }
}

const SECTIONS = [
  ["joints", "Joints"],
  ["tcp", "TCP"],
  ["io", "I/O"],
  ["registers", "Registers"],
  ["events", "Events"],
  ["audit", "Audit"],
] as const;

function WriteBlockedHint() {
  const { blockReason } = useWrites();
  if (blockReason === null) return null;
  return (
    <p className="hint" data-testid="write-blocked-reason">
      {blockReason}
    </p>
  );
}

function Panel({ runtime }: { runtime: LiveRuntime }) {
  const live = useLive();
  const [user, setUser] = useState<User | null>(null);
  const stale = live.health !== "connected";

  useEffect(() => {
    getMe()
      .then(setUser)
      .catch(() => setUser(null));
  }, []);

  const onUser = useCallback(
    (next: User | null) => {
      setUser(next);
      // A new socket carries the new session (control is tied to the holder's socket).
      runtime.stream.restart();
    },
    [runtime],
  );
  const onControl = useCallback((control: ControlStatus) => runtime.live.setControl(control), [runtime]);

  return (
    <WriteProvider user={user} live={live}>
      <div className="panel" data-testid="panel" data-stale={stale ? "true" : "false"}>
        <header className="panel-header">
          <StateBadge value={live.frame?.robot_state} stale={stale} size="panel" />
          <FlagBadges frame={live.frame} stale={stale} />
          <ConnectionHealth live={live} />
          <div className="panel-header__control">
            <ControlHolder control={live.control} />
            <SessionBar user={user} control={live.control} onUser={onUser} onControl={onControl} />
          </div>
        </header>
        <StaleBanner live={live} />
        {live.layoutMismatch !== null && (
          <div className="stale-banner" role="alert">
            The service uses layout version {live.layoutMismatch}; this page was built for another. Reload the page.
          </div>
        )}
        <nav className="panel-nav">
          {SECTIONS.map(([id, label]) => (
            <a key={id} href={`#${id}`}>
              {label}
            </a>
          ))}
        </nav>
        <main className={`panel-main${stale ? " is-stale" : ""}`}>
          <section id="joints">
            <h2>Joints</h2>
            <div className="plot-grid">
              {JOINT_PLOTS.map((spec) => (
                <LivePlotView key={spec.id} spec={spec} theme="light" />
              ))}
            </div>
          </section>
          <section id="tcp">
            <h2>TCP</h2>
            <div className="plot-grid">
              {TCP_PLOTS.map((spec) => (
                <LivePlotView key={spec.id} spec={spec} theme="light" />
              ))}
            </div>
          </section>
          <section id="io">
            <h2>I/O</h2>
            <WriteBlockedHint />
            <IoSection frame={live.frame} />
          </section>
          <section id="registers">
            <h2>Bit registers</h2>
            <RegistersSection frame={live.frame} />
          </section>
          <section id="events">
            <h2>Events</h2>
            <EventsView user={user} liveEvents={live.events} />
          </section>
          <section id="audit">
            <h2>Audit</h2>
            <AuditView user={user} liveEvents={live.events} />
          </section>
        </main>
      </div>
    </WriteProvider>
  );
}

export function PanelApp() {
  const runtime = useMemo(() => createLiveRuntime(ALL_PLOTS), []);
  useEffect(() => {
    runtime.start();
    window.__cobotHmi = runtime;
    return () => {
      runtime.stop();
      delete window.__cobotHmi;
    };
  }, [runtime]);
  return (
    <RuntimeContext.Provider value={runtime}>
      <Panel runtime={runtime} />
    </RuntimeContext.Provider>
  );
}
