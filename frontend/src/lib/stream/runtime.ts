/**
 * Layer: wiring of the live pipeline for one page (plain TypeScript, no React):
 * WebSocket (StreamClient) → LiveData (ring buffer + snapshot) → PlotCoordinator (rAF tick),
 * whose beat republishes the snapshot.
 */
import { LiveData } from "./liveData";
import { PlotCoordinator } from "../plots/plotCoordinator";
import type { PlotSpec } from "../plots/plots";
import { StreamClient, streamUrl } from "./stream";

export interface LiveRuntime {
  /** The robot streamed (null: the service's default robot); a plot's history is this robot's. */
  readonly robot: string | null;
  readonly live: LiveData;
  readonly stream: StreamClient;
  readonly coordinator: PlotCoordinator;
  start(): void;
  stop(): void;
}

export interface RuntimeOptions {
  /** The robot to stream (its name); null or undefined: the service's default robot. */
  readonly robot?: string | null;
  /** Frames per second wanted from the backend; undefined: every frame. */
  readonly rate_hz?: number;
  /** A session token for the stream's handshake (a kiosk of a site where viewing needs a login). */
  readonly token?: string | null;
  /**
   * The page's plot coordinator, for a pipeline whose plots share the page's redraw budget (the
   * panel's custom plots); it is not started or stopped here. Undefined: a coordinator of its own.
   */
  readonly coordinator?: PlotCoordinator;
}

export function createLiveRuntime(plots: readonly PlotSpec[], options: RuntimeOptions = {}): LiveRuntime {
  const live = new LiveData(plots);
  const stream = new StreamClient(() => streamUrl(window.location, options.robot ?? null, options.rate_hz, options.token), {
    onMessage: (m) => live.handle(m),
    onSocketState: (s) => live.setSocketState(s),
    onCloseReason: (r) => live.setCloseReason(r),
  });
  const shared = options.coordinator !== undefined;
  const coordinator = options.coordinator ?? new PlotCoordinator();
  let offBeat: (() => void) | null = null;
  return {
    robot: options.robot ?? null,
    live,
    stream,
    coordinator,
    start() {
      offBeat ??= coordinator.onBeat(() => live.beat());
      live.start();
      stream.start();
      if (!shared) coordinator.start();
    },
    stop() {
      if (!shared) coordinator.stop();
      stream.stop();
      live.stop();
      offBeat?.();
      offBeat = null;
    },
  };
}
