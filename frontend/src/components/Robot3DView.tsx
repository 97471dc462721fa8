/**
 * The robot in 3D, drawn from its joint angles with its model's kinematics and following the
 * frames live, with the flange's path over the last seconds. three.js is loaded when the view
 * first comes near the screen (its own chunk, lib/robot3d/robotScene3d.ts: a panel opened at its top
 * never fetches it until a person scrolls down to the view); samples go from the ring to the
 * scene in an animation-frame loop of its own, never through React state. On the panel the view turns by dragging,
 * by the arrow keys while it has the focus, or by its buttons (touch screens too); it zooms with
 * the wheel, + and −, or its buttons; "Reset view" (or 0) returns to the home view
 * (lib/robot3d/orbitCamera.ts: the steps and limits). The kiosk shows it without controls.
 *
 * For tests and the benchmark the view reports, as attributes of its figure (never React
 * state): `data-renders` (how often it drew), the camera (`data-camera-azimuth-deg`,
 * `-elevation-deg`, `-distance-mm`, whole numbers, on every change), and at most ten times a
 * second the joint angles drawn (`data-joints-deg`, one decimal) and the flange's path
 * (`data-tcp-path-points`, `data-tcp-path-mm` its length).
 */
import { memo, useEffect, useId, useRef, useState, type KeyboardEvent } from "react";
import { ARMS } from "../generated/arms";
import { ArmChain, armNameOf } from "../lib/robot3d/armKinematics";
import { actionOfKey, cameraReadout, type CameraAction } from "../lib/robot3d/orbitCamera";
import { DEFAULT_TRAIL_MS, pathLength, RobotPoseFeed } from "../lib/robot3d/robotPose";
import { useRuntime } from "./runtimeContext";
import "../styles/robot3d.css";

interface Props {
  /** The robot's model as the service reports it (its identity's product name), if known. */
  readonly model: string | null;
  readonly theme: "light" | "dark";
  /** Rotate, zoom and a reset button (the panel); false on the kiosk. */
  readonly interactive?: boolean;
  /** The drawing's height; "fill": the height of the box the view is put in (the kiosk's area). */
  readonly height_px?: number | "fill";
}

/** The view's buttons: what each does, its symbol and its name for a screen reader. */
const CAMERA_BUTTONS: readonly { action: CameraAction; symbol: string; label: string }[] = [
  { action: "rotate-left", symbol: "\u25C0", label: "Turn left" },
  { action: "rotate-right", symbol: "\u25B6", label: "Turn right" },
  { action: "rotate-up", symbol: "\u25B2", label: "View from higher" },
  { action: "rotate-down", symbol: "\u25BC", label: "View from lower" },
  { action: "zoom-in", symbol: "+", label: "Zoom in" },
  { action: "zoom-out", symbol: "\u2212", label: "Zoom out" },
];

/** How often at most the joint angles and the path are written to the page's attributes. */
const READOUT_INTERVAL_MS = 100;

/** three.js is fetched when the view is this near the screen (a scroll's worth ahead). */
const LOAD_AHEAD_MARGIN = "300px 0px";

/**
 * Whether `el` has come near the screen (once true, it stays true). Without IntersectionObserver
 * (an old browser) at once.
 */
function useNearScreen(el: { readonly current: Element | null }): boolean {
  const [near, setNear] = useState(() => typeof IntersectionObserver === "undefined");
  useEffect(() => {
    const target = el.current;
    if (near || target === null) return;
    const observer = new IntersectionObserver(
      (entries) => {
        if (entries.some((entry) => entry.isIntersecting)) setNear(true);
      },
      { rootMargin: LOAD_AHEAD_MARGIN },
    );
    observer.observe(target);
    return () => observer.disconnect();
  }, [el, near]);
  return near;
}

/** How far an arm reaches about (m): the sum of its joint offsets. */
function reachOf(chain: ArmChain): number {
  return chain.arm.joints.reduce((sum, j) => sum + Math.hypot(...j.originXyz_m), 0);
}

/** Memoised: the panel re-renders on each snapshot; the view draws from the ring on its own. */
export const Robot3DView = memo(function Robot3DView({ model, theme, interactive = true, height_px = 420 }: Props) {
  const { live } = useRuntime();
  const holder = useRef<HTMLDivElement | null>(null);
  const wrapper = useRef<HTMLDivElement | null>(null);
  const act = useRef<((action: CameraAction) => void) | null>(null);
  const [problem, setProblem] = useState<string | null>(null);
  const hintId = useId();
  const arm = armNameOf(model);
  const near = useNearScreen(wrapper);

  useEffect(() => {
    const el = holder.current;
    if (el === null || !near) return;
    let cancelled = false;
    let stop = () => undefined as void;
    import("../lib/robot3d/robotScene3d")
      .then(({ RobotScene }) => {
        if (cancelled) return;
        const chain = new ArmChain(ARMS[arm.name]);
        let feed: RobotPoseFeed;
        try {
          feed = new RobotPoseFeed(chain, live.ring, live.channels, DEFAULT_TRAIL_MS);
        } catch {
          setProblem("This page does not receive the joint positions.");
          return;
        }
        let scene: InstanceType<typeof RobotScene>;
        try {
          scene = new RobotScene(el, {
            theme,
            interactive,
            jointCount: chain.jointCount,
            trailCapacity: feed.trail.capacity + 1, // and the flange drawn
            reach_m: reachOf(chain),
          });
        } catch {
          setProblem("This browser cannot draw in 3D (WebGL is off or unavailable).");
          return;
        }
        setProblem(null);
        let dirty = true;
        let cameraMoved = true;
        scene.onCameraChange(() => {
          dirty = true;
          cameraMoved = true;
        });
        act.current = (action) => {
          scene.cameraAction(action);
          dirty = true;
          cameraMoved = true;
        };
        let trailCount = 0;
        let readoutAt_ms = -Infinity;
        let rendersShown = 0;
        const report = (now_ms: number) => {
          const data = wrapper.current?.dataset;
          if (data === undefined) return;
          if (scene.renders !== rendersShown) {
            rendersShown = scene.renders;
            data.renders = String(rendersShown);
          }
          if (cameraMoved) {
            cameraMoved = false;
            const camera = cameraReadout(scene.orbit());
            data.cameraAzimuthDeg = String(camera.azimuth_deg);
            data.cameraElevationDeg = String(camera.elevation_deg);
            data.cameraDistanceMm = String(camera.distance_mm);
          }
          if (now_ms - readoutAt_ms < READOUT_INTERVAL_MS) return;
          readoutAt_ms = now_ms;
          data.jointsDeg = Array.from(feed.drawn_deg, (v) => v.toFixed(1)).join(",");
          data.tcpPathPoints = String(trailCount);
          data.tcpPathMm = String(Math.round(pathLength(scene.trailArray, trailCount) * 1000));
        };
        const fit = () => {
          scene.resize(el.clientWidth, el.clientHeight);
          dirty = true;
        };
        fit();
        const observer = typeof ResizeObserver !== "undefined" ? new ResizeObserver(fit) : null;
        observer?.observe(el);
        // Out of view it keeps following (the path stays whole) but does not draw.
        let onScreen = true;
        const visibility =
          typeof IntersectionObserver !== "undefined"
            ? new IntersectionObserver((entries) => {
                for (const entry of entries) onScreen = entry.isIntersecting;
                if (onScreen) dirty = true;
              })
            : null;
        visibility?.observe(el);
        let handle = 0;
        const loop = (now_ms: number) => {
          handle = requestAnimationFrame(loop);
          feed.update();
          // The pose played back a little behind the newest frame, so it moves every frame.
          if (feed.poseAt(performance.now())) {
            scene.setPose(feed.frames);
            trailCount = feed.trailInto(scene.trailArray);
            scene.setTrailCount(trailCount);
            dirty = true;
          }
          if (dirty && feed.hasPose && onScreen) {
            dirty = false;
            scene.render();
          }
          if (feed.hasPose) report(now_ms);
        };
        handle = requestAnimationFrame(loop);
        stop = () => {
          cancelAnimationFrame(handle);
          observer?.disconnect();
          visibility?.disconnect();
          act.current = null;
          scene.dispose();
        };
      })
      .catch(() => {
        if (!cancelled) setProblem("The 3D view could not be loaded.");
      });
    return () => {
      cancelled = true;
      stop();
    };
  }, [live, arm.name, theme, interactive, near]);

  const onKeyDown = (event: KeyboardEvent<HTMLDivElement>) => {
    const action = actionOfKey(event.key, { ctrl: event.ctrlKey, alt: event.altKey, meta: event.metaKey });
    if (action === null || act.current === null) return;
    event.preventDefault(); // the arrows would scroll the page
    act.current(action);
  };
  const canvasLabel = `${arm.name} in 3D`;
  const fill = height_px === "fill";
  const canvasStyle = fill ? undefined : { height: `${height_px}px` };

  return (
    <figure className={`robot3d robot3d--${theme}${fill ? " robot3d--fill" : ""}`} data-testid="robot-3d" data-arm={arm.name} data-renders="0" ref={wrapper}>
      <figcaption className="robot3d__header">
        <span className="robot3d__title">
          {arm.name}
          {!arm.known && <span className="robot3d__assumed"> (model not reported: drawn as the {arm.name})</span>}
        </span>
        {interactive && (
          <span className="robot3d__controls">
            <span className="robot3d__hint" id={hintId}>
              drag or arrow keys to turn, wheel or + − to zoom, right-drag to pan, 0 to reset
            </span>
            <span className="robot3d__buttons" role="group" aria-label="3D view camera">
              {CAMERA_BUTTONS.map(({ action, symbol, label }) => (
                <button
                  key={action}
                  type="button"
                  className="robot3d__button"
                  data-testid={`robot-3d-${action}`}
                  aria-label={label}
                  title={label}
                  onClick={() => act.current?.(action)}
                >
                  <span aria-hidden="true">{symbol}</span>
                </button>
              ))}
              <button type="button" className="robot3d__button robot3d__button--reset" data-testid="robot-3d-reset" onClick={() => act.current?.("reset")}>
                Reset view
              </button>
            </span>
          </span>
        )}
      </figcaption>
      {problem !== null && (
        <p className="robot3d__problem" role="status">
          {problem}
        </p>
      )}
      {interactive ? (
        // Focusable so the keys reach it; "application": a screen reader passes the arrows on.
        <div
          className="robot3d__canvas"
          ref={holder}
          style={canvasStyle}
          tabIndex={0}
          role="application"
          aria-label={`${canvasLabel}: arrow keys turn the view, + and − zoom, 0 resets`}
          aria-describedby={hintId}
          data-testid="robot-3d-canvas"
          onKeyDown={onKeyDown}
        />
      ) : (
        <div className="robot3d__canvas" ref={holder} style={canvasStyle} role="img" aria-label={canvasLabel} data-testid="robot-3d-canvas" />
      )}
    </figure>
  );
});
