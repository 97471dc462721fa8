/**
 * The robot in 3D, drawn from its joint angles with its model's kinematics and following the
 * frames live, with the flange's path over the last seconds. three.js is loaded with this view
 * (its own chunk, lib/robotScene3d.ts); samples go from the ring to the scene in an animation-
 * frame loop of its own, never through React state. Rotate by dragging, zoom with the wheel,
 * "Reset view" returns to the home view; the kiosk shows it without controls.
 */
import { useEffect, useRef, useState } from "react";
import { ARMS } from "../generated/arms";
import { ArmChain, armNameOf } from "../lib/armKinematics";
import { DEFAULT_TRAIL_MS, RobotPoseFeed } from "../lib/robotPose";
import { useRuntime } from "./runtimeContext";
import "../styles/robot3d.css";

interface Props {
  /** The robot's model as the service reports it (its identity's product name), if known. */
  readonly model: string | null;
  readonly theme: "light" | "dark";
  /** Rotate, zoom and a reset button (the panel); false on the kiosk. */
  readonly interactive?: boolean;
  readonly height_px?: number;
}

/** How far an arm reaches about (m): the sum of its joint offsets. */
function reachOf(chain: ArmChain): number {
  return chain.arm.joints.reduce((sum, j) => sum + Math.hypot(...j.originXyz_m), 0);
}

export function Robot3DView({ model, theme, interactive = true, height_px = 420 }: Props) {
  const { live } = useRuntime();
  const holder = useRef<HTMLDivElement | null>(null);
  const wrapper = useRef<HTMLDivElement | null>(null);
  const reset = useRef<(() => void) | null>(null);
  const [problem, setProblem] = useState<string | null>(null);
  const arm = armNameOf(model);

  useEffect(() => {
    const el = holder.current;
    if (el === null) return;
    let cancelled = false;
    let stop = () => undefined as void;
    import("../lib/robotScene3d")
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
        scene.onCameraChange(() => {
          dirty = true;
        });
        reset.current = () => {
          scene.resetView();
          dirty = true;
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
        const loop = () => {
          handle = requestAnimationFrame(loop);
          feed.update();
          // The pose played back a little behind the newest frame, so it moves every frame.
          if (feed.poseAt(performance.now())) {
            scene.setPose(feed.frames);
            scene.setTrailCount(feed.trailInto(scene.trailArray));
            dirty = true;
          }
          if (!dirty || !feed.hasPose || !onScreen) return;
          dirty = false;
          scene.render();
          // For tests and the benchmark: how often it drew (an attribute, not React state).
          if (wrapper.current !== null) wrapper.current.dataset.renders = String(scene.renders);
        };
        handle = requestAnimationFrame(loop);
        stop = () => {
          cancelAnimationFrame(handle);
          observer?.disconnect();
          visibility?.disconnect();
          reset.current = null;
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
  }, [live, arm.name, theme, interactive]);

  return (
    <figure className={`robot3d robot3d--${theme}`} data-testid="robot-3d" data-arm={arm.name} data-renders="0" ref={wrapper}>
      <figcaption className="robot3d__header">
        <span className="robot3d__title">
          {arm.name}
          {!arm.known && <span className="robot3d__assumed"> (model not reported: drawn as the {arm.name})</span>}
        </span>
        {interactive && (
          <span className="robot3d__controls">
            <span className="robot3d__hint">drag to rotate, wheel to zoom, right-drag to pan</span>
            <button type="button" data-testid="robot-3d-reset" onClick={() => reset.current?.()}>
              Reset view
            </button>
          </span>
        )}
      </figcaption>
      {problem !== null && (
        <p className="robot3d__problem" role="status">
          {problem}
        </p>
      )}
      <div className="robot3d__canvas" ref={holder} style={{ height: `${height_px}px` }} />
    </figure>
  );
}
