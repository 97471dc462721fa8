/**
 * The kiosk (`/kiosk?robot=NAME&tiles=joint_position,tcp_position`; without `robot`, the
 * service's default robot; `tiles` chooses its large numeric tiles, any numeric field of the
 * frame; `robot3d=1` adds the 3D view of the robot's model, `arm=M0609` overrides it): read-only by
 * construction. Its component tree imports no write control,
 * no REST module and no login (a test walks its imports); it reads the WebSocket only. Light or
 * dark as the system says (or `theme=light|dark` in its URL), readable from three metres, cursor hidden, reconnects by itself, bounded memory, and shifts a
 * few pixels now and then against burn-in without ever hiding the state or an emergency stop.
 *
 * Everything it shows fits its screen without scrolling, whatever the screen: sizes are
 * multiples of the scale `--u` (lib/kiosk/kioskLayout.ts: design pixels of a 1920 × 1080 screen), the
 * header, the banners and the lamps take the room their text needs, and the body (tiles, plots,
 * the 3D view) is laid out in what they leave (useKioskLayout.ts).
 */
import { useEffect, useMemo, useRef, useState, type CSSProperties } from "react";
import { AlarmBanner } from "../components/AlarmBanner";
import { ConnectionHealth } from "../components/ConnectionHealth";
import { ControlHolder } from "../components/ControlHolder";
import { FlagBadges } from "../components/FlagBadges";
import { LivePlotView } from "../components/LivePlotView";
import { RuntimeContext, useLive } from "../components/runtimeContext";
import { StaleBanner } from "../components/StaleBanner";
import { Robot3DView } from "../components/Robot3DView";
import { StateBadge } from "../components/StateBadge";
import { TagNamesContext } from "../components/tagNames";
import { useTheme } from "../components/theme";
import { burnInOffset, BURN_IN_PERIOD_MS } from "../lib/kiosk/burnIn";
import { timeZoneLabel } from "../lib/common/dates";
import { tileShape, tilesFromSearch } from "../lib/kiosk/kioskTiles";
import { JOINT_PLOTS, TCP_PLOTS, type PlotSpec } from "../lib/plots/plots";
import { robotFromSearch } from "../lib/common/route";
import { createLiveRuntime } from "../lib/stream/runtime";
import { fetchTagNames } from "../lib/layout/tagNames";
import type { TagNames } from "../lib/layout/tags";
import { KioskLamps } from "./KioskLamps";
import { KioskOtherAlarms } from "./KioskOtherAlarms";
import { kioskOtherAlarms } from "../lib/kiosk/kioskOtherAlarms";
import { CYCLE_TILE, withCycleTimes } from "../lib/kiosk/cyclesTile";
import { kioskPlotWindow_ms } from "../lib/kiosk/kioskLayout";
import { KioskClock, KioskStateWords, KioskTiles } from "./KioskTiles";
import { usePlotHeight, useKioskLayout } from "./useKioskLayout";
import { useKioskCycleTimes } from "./useKioskCycleTimes";
import { useKioskMaintenance } from "./useKioskMaintenance";
import { useRobotModel } from "./useRobotModel";
import "../styles/kiosk.css";
import "../styles/kioskMaintenance.css";

const KIOSK_PLOTS: readonly PlotSpec[] = [JOINT_PLOTS[0], TCP_PLOTS[0]].filter((p): p is PlotSpec => p !== undefined);
/** A kiosk does not need every frame: 25 per second keeps a small PC cool for days. */
const KIOSK_RATE_HZ = 25;
/** Tag names change seldom (an admin renames a point): asked again this often. */
const TAGS_REFRESH_MS = 60_000;

/** The robot's tag names for the lamps, read with a plain GET (the kiosk has no REST client). */
function useKioskTagNames(robot: string | null, token: string | null): TagNames {
  const [tags, setTags] = useState<TagNames>({});
  useEffect(() => {
    if (robot === null) return;
    let cancelled = false;
    const load = () =>
      fetchTagNames(robot, token)
        .then((names) => {
          if (!cancelled && names !== null) setTags(names);
        })
        .catch(() => undefined);
    void load();
    const timer = setInterval(() => void load(), TAGS_REFRESH_MS);
    return () => {
      cancelled = true;
      clearInterval(timer);
    };
  }, [robot, token]);
  return tags;
}

function useBurnInOffset() {
  const [now, setNow] = useState(() => Date.now());
  useEffect(() => {
    const timer = setInterval(() => setNow(Date.now()), BURN_IN_PERIOD_MS / 4);
    return () => clearInterval(timer);
  }, []);
  return burnInOffset(now);
}

/** What the kiosk's URL chooses besides the robot (read once: a kiosk's URL does not change). */
function kioskOptions(search: string) {
  const params = new URLSearchParams(search);
  return {
    tiles: tilesFromSearch(search),
    robot3d: params.get("robot3d") === "1",
    arm: params.get("arm"),
    token: params.get("token"),
  };
}

/** One live plot in a slot of the body: its plotting area as high as the slot leaves it. */
function KioskPlot({ spec, theme, slotHeight_px, u, window_ms }: { spec: PlotSpec; theme: "light" | "dark"; slotHeight_px: number; u: number; window_ms: number }) {
  const slot = useRef<HTMLDivElement | null>(null);
  const height_px = usePlotHeight(slot, slotHeight_px, u);
  return (
    <div className="kiosk__plot" ref={slot}>
      <LivePlotView spec={spec} theme={theme} readOnly height_px={height_px} initialWindow_ms={window_ms} />
    </div>
  );
}

function Kiosk() {
  const [options] = useState(() => kioskOptions(window.location.search));
  const live = useLive();
  const offset = useBurnInOffset();
  const tags = useKioskTagNames(live.robot, options.token);
  const maintenance = useKioskMaintenance(live.robot, options.token);
  const cycleTimes = useKioskCycleTimes(live.robot, options.token, options.tiles.fields.includes(CYCLE_TILE), live.kiosk?.shift_starts);
  // The 3D view's arm: `arm=` in the URL, else the model the service reports for the robot.
  const model = useRobotModel(options.robot3d && options.arm === null ? live.robot : null, options.token);
  const stale = live.health !== "connected";
  const frame = live.frame;
  const estop = frame?.emergency_stopped === true;
  const plotWindow_ms = kioskPlotWindow_ms(live.kiosk);
  const otherAlarms = kioskOtherAlarms(live.cellAlarms, live.robot);
  const theme = useTheme();
  const content = useMemo(
    () => ({
      tiles: options.tiles.fields.map(tileShape),
      unknownLine: options.tiles.unknown.length > 0,
      robot3d: options.robot3d,
      plots: KIOSK_PLOTS.length,
    }),
    [options],
  );
  const body = useRef<HTMLElement | null>(null);
  const layout = useKioskLayout(
    body,
    content,
    // What changes the room the header and banners leave: a relayout from the full scale.
    [estop, stale, live.alarms.length > 0, otherAlarms.length, live.robot, live.control.holder?.user ?? null, maintenance.words ?? ""].join("|"),
  );
  const style = {
    gridTemplateColumns: layout.body?.columns,
    gridTemplateRows: layout.body?.rows,
    gridTemplateAreas: layout.body?.areas,
  } as CSSProperties;
  return (
    <TagNamesContext.Provider value={tags}>
      <div
        className={`kiosk kiosk--${layout.landscape ? "landscape" : "portrait"}`}
        data-testid="kiosk"
        data-stale={stale ? "true" : "false"}
        data-scale={layout.u.toFixed(3)}
        data-fits={layout.body?.fits === false ? "false" : "true"}
        style={{ "--u": layout.u } as CSSProperties}
      >
        <div
          className="kiosk__shift"
          data-testid="kiosk-shift"
          style={{ transform: `translate(${offset.dx_px}px, ${offset.dy_px}px)` }}
        >
          <header className="kiosk__header">
            <h1 className="visually-hidden">Kiosk{live.robot !== null ? ` of ${live.robot}` : ""}</h1>
            <div className="kiosk__top">
              <div className="kiosk__ident">
                {live.robot !== null && (
                  <div className="kiosk__robot" data-testid="kiosk-robot">
                    {live.robot}
                  </div>
                )}
                <div className="kiosk__time">
                  <KioskClock />
                  <span className="kiosk__zone" data-testid="kiosk-zone">
                    {timeZoneLabel(Date.now())}
                  </span>
                </div>
              </div>
              <StateBadge value={frame?.robot_state} stale={stale} size="kiosk" />
              {/* Robot health asks for a look (issue 40): seen from the cell, never above a stop. */}
              {maintenance.due && (
                <div className="kiosk__maintenance" data-testid="kiosk-maintenance-due" data-verdict={maintenance.verdict ?? ""} role="status">
                  {maintenance.words}
                </div>
              )}
              {estop && (
                <div className="kiosk__estop" data-testid="kiosk-estop" role="alert">
                  EMERGENCY STOP
                </div>
              )}
            </div>
            <div className="kiosk__facts">
              <FlagBadges frame={frame} stale={stale} />
              <ControlHolder control={live.control} />
              <KioskStateWords value={frame?.robot_state} />
              <ConnectionHealth live={live} compact />
            </div>
          </header>
          {/* Above everything but the state; read-only: the stream's alarms, no acknowledge here. */}
          <AlarmBanner alarms={live.alarms} size="kiosk" />
          {/* The other robots' critical and unacknowledged alarms: a line each, naming the robot. */}
          <KioskOtherAlarms lines={otherAlarms} />
          <StaleBanner live={live} />
          {/* The page's main landmark: what the kiosk is for, below its header and banners. */}
          <main className={`kiosk__body${stale ? " is-stale" : ""}`} ref={body} style={style}>
            {(options.tiles.fields.length > 0 || options.tiles.unknown.length > 0) && (
              <div className="kiosk__tiles-area">
                <KioskTiles fields={options.tiles.fields} unknown={options.tiles.unknown} frame={withCycleTimes(frame, cycleTimes)} grid={layout.body?.tileGrid ?? null} />
              </div>
            )}
            <div className={`kiosk__plots${layout.body?.plotsAcross === true ? " kiosk__plots--across" : ""}`}>
              {/* Drawn once the body's room is known (a plot is built for its height). */}
              {layout.body !== null &&
                KIOSK_PLOTS.map((spec) => (
                  // Rebuilt with the window the service sets (its hello: at least a cycle).
                  <KioskPlot key={`${spec.id}|${plotWindow_ms}`} spec={spec} theme={theme} slotHeight_px={layout.body?.plot.height_px ?? 0} u={layout.u} window_ms={plotWindow_ms} />
                ))}
            </div>
            {options.robot3d && (
              <div className="kiosk__robot3d">
                <Robot3DView model={options.arm ?? model} theme={theme} interactive={false} height_px="fill" />
              </div>
            )}
          </main>
          <KioskLamps frame={frame} />
        </div>
      </div>
    </TagNamesContext.Provider>
  );
}

export function KioskApp() {
  // Where viewing needs a login, a kiosk is opened as /kiosk?token=… (a viewer's token): the
  // token goes into the stream's handshake; there is still no login form and no write here.
  const runtime = useMemo(
    () =>
      createLiveRuntime(KIOSK_PLOTS, {
        robot: robotFromSearch(window.location.search),
        rate_hz: KIOSK_RATE_HZ,
        token: new URLSearchParams(window.location.search).get("token"),
      }),
    [],
  );
  useEffect(() => {
    runtime.start();
    return () => runtime.stop();
  }, [runtime]);
  return (
    <RuntimeContext.Provider value={runtime}>
      <Kiosk />
    </RuntimeContext.Provider>
  );
}
