/**
 * The commissioning panel (`/?robot=NAME`): one robot at a time, chosen in the header (the
 * service's first robot without `?robot=`). State, flags, connection health and control always
 * visible in a sticky header; live joint and TCP plots; I/O and registers with writes; events
 * and audit. Switching robot builds a new live pipeline (its own stream) for the new robot.
 */
import { useCallback, useEffect, useMemo, useRef, useState, useSyncExternalStore } from "react";
import { AlarmBanner } from "../components/AlarmBanner";
import { ConnectionHealth } from "../components/ConnectionHealth";
import { ControlHolder } from "../components/ControlHolder";
import { CustomPlots } from "../components/CustomPlots";
import { FlagBadges } from "../components/FlagBadges";
import { JointTable } from "../components/JointTable";
import { LivePlotView } from "../components/LivePlotView";
import { PlotHistoryContext, type PlotHistoryAccess } from "../components/plotHistory";
import { Robot3DView } from "../components/Robot3DView";
import { RuntimeContext, useLive } from "../components/runtimeContext";
import { StaleBanner } from "../components/StaleBanner";
import { StateBadge } from "../components/StateBadge";
import { TcpReadout } from "../components/TcpReadout";
import { TagNamesContext } from "../components/tagNames";
import { ThemeSwitch, useTheme } from "../components/theme";
import { api } from "../lib/api/api";
import { alarmsByRobot, otherRobotAlarms } from "../lib/alarms/alarmsCell";
import { FleetPoller, knownRobots, type FleetTile } from "../lib/fleet/fleet";
import { historyFetcher } from "../lib/history/historyApi";
import { ALL_PLOTS, JOINT_PLOTS, TCP_PLOTS } from "../lib/plots/plots";
import type { ControlStatus, User } from "../lib/api/protocol";
import { chooseRobot, rangeFromSearch, robotFromSearch, searchWithRobot } from "../lib/common/route";
import { controlOwnership } from "../lib/writes/controlSession";
import { createLiveRuntime, type LiveRuntime } from "../lib/stream/runtime";
import type { TagNames } from "../lib/layout/tags";
import { PlotTimeRange } from "../lib/plots/timeRange";
import { AlarmCue } from "./AlarmCue";
import { AlarmsView } from "./AlarmsView";
import { CheckoutView } from "./CheckoutView";
import { CycleView } from "./CycleView";
import { AuditView, EventsView } from "./EventsView";
import { IoSection } from "./IoSection";
import { FoldedPlots, JOINT_LABEL_VARS, PhoneStream, useNarrow } from "./PhoneView";
import { PresetsView } from "./PresetsView";
import { RegistersSection } from "./RegistersSection";
import { RobotSwitcher } from "./RobotSwitcher";
import { SessionBar } from "./SessionBar";
import { TagsView } from "./TagsView";
import { WriteProvider, useWrites } from "./writeContext";
import "../styles/panel.css";
import "../styles/print.css";
import "../styles/readouts.css";
import "../styles/phone.css";

declare global {
  interface Window {
    /** The live pipeline, for the UI benchmark and debugging in the console. */
    __cobotHmi?: LiveRuntime;
  }
}

/** How often the switcher's list of robots (and their link states) is refreshed. */
const ROBOTS_POLL_MS = 5000;

const SECTIONS = [
  ["joints", "Joints"],
  ["tcp", "TCP"],
  ["custom", "Custom plots"],
  ["robot3d", "3D"],
  ["alarms", "Alarms"],
  ["io", "I/O"],
  ["registers", "Registers"],
  ["cycles", "Cycles"],
  ["events", "Events"],
  ["audit", "Audit"],
  ["tags", "Tag names"],
  ["checkout", "Checkout"],
  ["presets", "Presets"],
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

interface PanelProps {
  readonly robot: string;
  readonly robots: readonly FleetTile[];
  readonly onSelect: (robot: string) => void;
  readonly user: User | null;
  readonly onUser: (user: User | null) => void;
}

function Panel({ runtime, robot, robots, onSelect, user, onUser }: PanelProps & { runtime: LiveRuntime }) {
  const live = useLive();
  const theme = useTheme();
  const stale = live.health !== "connected";

  const onSessionUser = useCallback(
    (next: User | null) => {
      onUser(next);
      // A new socket carries the new session (control is tied to the holder's socket).
      runtime.stream.restart();
    },
    [runtime, onUser],
  );
  const onControl = useCallback((control: ControlStatus) => runtime.live.setControl(control), [runtime]);
  // Our own logout closes our stream (1008): reconnect at once rather than show "session ended".
  const expectSessionEnd = useCallback(() => runtime.stream.expectSessionEnd(), [runtime]);
  const ownership = controlOwnership(live.control, user, live.session);
  const newestAlarmEvent = live.events.find((e) => e.kind === "alarm")?.time ?? null;
  const [tags, setTags] = useState<TagNames>({});
  // A phone's header shows only the essentials; the rest opens below them (styles/responsive.css).
  const [menuOpen, setMenuOpen] = useState(false);
  const openMenu = useCallback(() => setMenuOpen(true), []);
  // Kept while the list is the same: the custom plots are not rendered again with every snapshot.
  const robotNamesKey = robots.map((r) => r.name).join("\n");
  const robotNames = useMemo(() => (robotNamesKey === "" ? [] : robotNamesKey.split("\n")), [robotNamesKey]);
  const model = robots.find((r) => r.name === robot)?.model ?? null;
  // A phone: plots folded until asked for, the stream only what is in view (PhoneView.tsx).
  const narrow = useNarrow();
  const [plotsOpen, setPlotsOpen] = useState(false);
  const openPlots = useCallback(() => setPlotsOpen(true), []);

  return (
    <TagNamesContext.Provider value={tags}>
      <WriteProvider robot={robot} user={user} live={live}>
        <div className="panel" data-testid="panel" data-robot={robot} data-stale={stale ? "true" : "false"}>
          <PhoneStream runtime={runtime} narrow={narrow} plotsOpen={plotsOpen} />
          <header
            id="panel-header"
            className={`panel-header${menuOpen ? " is-menu-open" : ""}`}
            data-testid="panel-header"
            onKeyDown={(e) => {
              if (e.key === "Escape" && menuOpen) setMenuOpen(false);
            }}
          >
            <h1 className="visually-hidden">Panel of {robot}</h1>
            <RobotSwitcher robot={robot} robots={robots} onSelect={onSelect} alarms={alarmsByRobot(live.cellAlarms)} />
            <StateBadge value={live.frame?.robot_state} stale={stale} size="panel" />
            <FlagBadges frame={live.frame} stale={stale} />
            <ConnectionHealth live={live} />
            <div className="panel-header__control">
              <ControlHolder control={live.control} ownership={ownership} />
              <SessionBar
                robot={robot}
                user={user}
                ownership={ownership}
                onUser={(next) => {
                  // Logged in or out: the phone's header back to its essentials.
                  setMenuOpen(false);
                  onSessionUser(next);
                }}
                onControl={onControl}
                onLoginWanted={openMenu}
                onLoggingOut={expectSessionEnd}
              />
            </div>
            <button
              type="button"
              className="panel-header__menu"
              data-testid="header-menu"
              aria-expanded={menuOpen}
              aria-controls="panel-header"
              title={menuOpen ? "Show only the essentials" : "Flags, connection figures, links and session"}
              onClick={() => setMenuOpen((open) => !open)}
            >
              <span aria-hidden="true">{menuOpen ? "✕" : "☰"}</span> {menuOpen ? "Less" : "More"}
            </button>
            {/* In the sticky header: an alarm stays in view wherever the page is scrolled. */}
            <AlarmBanner alarms={live.alarms} size="panel" listHref="#alarms" others={otherRobotAlarms(live.cellAlarms, robot)}>
              <AlarmCue alarms={live.alarms} />
            </AlarmBanner>
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
            <ThemeSwitch />
          </nav>
          <main className={`panel-main${stale ? " is-stale" : ""}`}>
            <section id="joints">
              <h2>Joints</h2>
              <div className="readouts" style={JOINT_LABEL_VARS}>
                <JointTable stale={stale} />
                <TcpReadout stale={stale} />
              </div>
              <FoldedPlots narrow={narrow} open={plotsOpen} onOpen={openPlots} label="Show the plots">
                <div className="plot-grid">
                  {JOINT_PLOTS.map((spec) => (
                    <LivePlotView key={spec.id} spec={spec} theme={theme} />
                  ))}
                </div>
              </FoldedPlots>
            </section>
            <section id="tcp">
              <h2>TCP</h2>
              <FoldedPlots narrow={narrow} open={plotsOpen} onOpen={openPlots} label="Show the plots">
                <div className="plot-grid">
                  {TCP_PLOTS.map((spec) => (
                    <LivePlotView key={spec.id} spec={spec} theme={theme} />
                  ))}
                </div>
              </FoldedPlots>
            </section>
            <section id="custom">
              <h2>Custom plots</h2>
              <CustomPlots robot={robot} robots={robotNames} coordinator={runtime.coordinator} />
            </section>
            <section id="robot3d">
              <h2>3D</h2>
              <Robot3DView model={model} theme={theme} />
            </section>
            <section id="alarms">
              <h2>Alarms</h2>
              <AlarmsView robot={robot} user={user} alarms={live.alarms} newestEvent={newestAlarmEvent} />
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
            <section id="cycles">
              <h2>Cycle timing</h2>
              <CycleView robot={robot} theme={theme} />
            </section>
            <section id="events">
              <h2>Events</h2>
              <EventsView robot={robot} user={user} liveEvents={live.events} />
            </section>
            <section id="audit">
              <h2>Audit</h2>
              <AuditView robot={robot} user={user} liveEvents={live.events} />
            </section>
            <section id="tags">
              <h2>Tag names</h2>
              <TagsView robot={robot} user={user} onTags={setTags} />
            </section>
            <section id="checkout">
              <h2>I/O checkout</h2>
              <CheckoutView robot={robot} user={user} />
            </section>
            <section id="presets">
              <h2>Output presets</h2>
              <PresetsView robot={robot} user={user} />
            </section>
          </main>
        </div>
      </WriteProvider>
    </TagNamesContext.Provider>
  );
}

/** One robot's panel: its own live pipeline, started while it is shown. */
function RobotPanel(props: PanelProps) {
  const { robot } = props;
  const runtime = useMemo(() => createLiveRuntime(ALL_PLOTS, { robot }), [robot]);
  useEffect(() => {
    runtime.start();
    window.__cobotHmi = runtime;
    return () => {
      runtime.stop();
      if (window.__cobotHmi === runtime) delete window.__cobotHmi;
    };
  }, [runtime]);
  // The plots reach the recording through the REST client; a marker's jump moves them all.
  const plotHistory = useMemo<PlotHistoryAccess>(
    // A link naming a range (the plant page's History: `?robot=&from=&to=`) opens the plots there.
    () => ({ fetcher: (name, fields) => historyFetcher(api.client, name, fields), timeRange: new PlotTimeRange().openAt(rangeFromSearch(window.location.search)) }),
    [],
  );
  return (
    <RuntimeContext.Provider value={runtime}>
      <PlotHistoryContext.Provider value={plotHistory}>
        <Panel runtime={runtime} {...props} />
      </PlotHistoryContext.Provider>
    </RuntimeContext.Provider>
  );
}

/**
 * Before a robot is known: why not, and the login (where viewing needs one). Not while the robots
 * are still being asked for: the panel with its own login follows in a moment, and a name typed
 * into this one would be lost with it (a test typing at once saw its user name vanish).
 */
function NoRobot({ reason, login, user, onUser }: { reason: string; login: boolean; user: User | null; onUser: (user: User | null) => void }) {
  return (
    <div className="panel" data-testid="panel">
      <header className="panel-header">
        <h1 className="visually-hidden">Panel</h1>
        <p className="hint" data-testid="robots-reason">
          {reason}
        </p>
        <div className="panel-header__control">
          {login && user === null && <SessionBar robot="" user={null} ownership="nobody" onUser={onUser} onControl={() => undefined} />}
        </div>
      </header>
    </div>
  );
}

export function PanelApp() {
  const [wanted, setWanted] = useState(() => robotFromSearch(window.location.search));
  const [user, setUser] = useState<User | null>(null);

  useEffect(() => {
    api
      .me()
      .then(setUser)
      .catch(() => setUser(null));
  }, []);

  // The service's robots for the switcher, polled (their link states change), and asked again
  // at once after a login or logout (a site may require a login to view anything).
  const poller = useMemo(() => new FleetPoller(() => api.robots(), ROBOTS_POLL_MS), []);
  useEffect(() => {
    poller.start();
    return () => poller.stop();
  }, [poller]);
  const seenUser = useRef<User | null | undefined>(undefined);
  useEffect(() => {
    // Not on the first render: start() has just asked.
    if (seenUser.current !== undefined) poller.refresh();
    seenUser.current = user;
  }, [poller, user]);
  const fleet = useSyncExternalStore(poller.subscribe, poller.getSnapshot);
  const known = knownRobots(fleet);

  // Back and forward move between robots as they move between pages.
  useEffect(() => {
    const onPop = () => setWanted(robotFromSearch(window.location.search));
    window.addEventListener("popstate", onPop);
    return () => window.removeEventListener("popstate", onPop);
  }, []);

  const onSelect = useCallback((next: string) => {
    window.history.pushState(null, "", `${window.location.pathname}${searchWithRobot(window.location.search, next)}`);
    setWanted(next);
  }, []);

  const { robot, unknown } = chooseRobot(wanted, known);

  // A URL without a robot is given the one shown, so that it can be copied as a link to it.
  useEffect(() => {
    if (wanted !== null || robot === null) return;
    window.history.replaceState(null, "", `${window.location.pathname}${searchWithRobot(window.location.search, robot)}`);
    setWanted(robot);
  }, [wanted, robot]);

  if (robot === null) {
    const reason =
      unknown !== null
        ? `The service has no robot "${unknown}".`
        : fleet.error !== null
          ? `The robots of the service are unknown: ${fleet.error}`
          : known !== null
            ? "The service has no robot."
            : "Asking the service for its robots…";
    const asking = unknown === null && fleet.error === null && known === null;
    return <NoRobot reason={reason} login={!asking} user={user} onUser={setUser} />;
  }
  return (
    <>
      {unknown !== null && (
        <div className="stale-banner" role="alert" data-testid="unknown-robot">
          The service has no robot "{unknown}"; showing {robot}.
        </div>
      )}
      <RobotPanel key={robot} robot={robot} robots={fleet.tiles} onSelect={onSelect} user={user} onUser={setUser} />
    </>
  );
}
