/**
 * Layer: the live-data store between the WebSocket and the views (plain TypeScript, no React).
 *
 * Frames go into a fixed-size sample ring (for the plots) and a "latest frame" slot; React reads
 * an immutable snapshot that is republished every `publishInterval_ms` or so (and at once on
 * status, control, event, state, flag and socket changes), so a 100 Hz stream never means 100
 * React renders a second. The page's beat republishes it (`beat()`, from the plot coordinator:
 * React's render then lands in the animation frame the plots are drawn in, one change of the
 * page's picture instead of two); a timer does when no beat comes (a hidden page, no
 * coordinator). Everything held is bounded (ring, event list), so memory stays flat over days.
 * Must not import React or any component.
 */
import { alarmsFromHello, applyAlarm, type Alarm } from "../alarms/alarms";
import { setSiteTimeZone } from "../common/dates";
import { connectionHealth, type Health, type SocketState } from "./health";
import { LAYOUT, LAYOUT_VERSION, type FieldInfo, type Frame } from "../../generated/layout";
import { FLAG_FIELDS, isFlagField } from "../layout/layoutInfo";
import { ChannelMap, type PlotSpec } from "../plots/plots";
import type { CellAlarmSummary, ConnectionStatus, ControlStatus, KioskConfig, ServerMessage, StreamEvent } from "../api/protocol";
import { SampleRing } from "./ringBuffer";

/** 32768 samples: over 5 minutes at RPI 10 ms, so a 2-minute window is always full. */
export const RING_CAPACITY = 32_768;
/** Newest events kept for the live table. */
export const EVENT_LIMIT = 200;

export interface LiveSnapshot {
  readonly frame: Frame | null;
  /** the stream's number (`seq`) of the newest frame: a write's confirmation names its frame so */
  readonly frameSeq: number | null;
  /** backend receive time of the newest frame (s since the epoch) */
  readonly frameTime_s: number | null;
  /** ms since the browser received the newest frame */
  readonly frameAge_ms: number | null;
  readonly socket: SocketState;
  readonly connection: ConnectionStatus | null;
  readonly control: ControlStatus;
  readonly health: Health;
  /** When the display stopped being live (browser clock, ms since the epoch), null while live. */
  readonly staleSince_ms: number | null;
  readonly framesReceived: number;
  /** frames missing in the backend's sequence as this browser saw it */
  readonly clientGaps: number;
  /** frames the backend dropped for this browser (it read too slowly) */
  readonly dropped: number;
  readonly events: readonly StreamEvent[];
  /** the backend speaks another layout version than this build */
  readonly layoutMismatch: number | null;
  readonly rate_hz: number | null;
  /** Why the service closed the stream last, if it said so. */
  readonly closeReason: string | null;
  /** The fields the frames carry (the page's subscription; null: every field). */
  readonly fields: readonly string[] | null;
  /** The kiosk's settings as the hello gave them (null: before the hello, or an older service). */
  readonly kiosk: KioskConfig | null;
  /** The robot's name as the stream's hello gave it (null: before the hello). */
  readonly robot: string | null;
  /** The robot's current alarms (hello, then `alarm` events), most urgent first (lib/alarms/alarms.ts). */
  readonly alarms: readonly Alarm[];
  /** This stream's login session as the hello named it (null: none), to tell whose control it is. */
  readonly session: string | null;
  /** Every robot's alarms at a glance (hello, then each status; null: the service does not say). */
  readonly cellAlarms: CellAlarmSummary | null;
}

/**
 * How often the snapshot is republished without a change that shows at once: the numbers React
 * renders (the frame age, I/O values, the header's figures) a few times a second; the readouts
 * beside the plots follow the stream on their own (components/LiveCells.tsx).
 */
export const PUBLISH_INTERVAL_MS = 250;

export interface LiveDataOptions {
  readonly capacity?: number;
  readonly publishInterval_ms?: number;
  readonly now?: () => number;
}

type Listener = () => void;

const FLAG_NAMES = FLAG_FIELDS.map((f) => f.name).filter(isFlagField);

/**
 * A frame with every field unknown (arrays of nulls, null scalars): what a subscribed frame's
 * absent fields read as, so a view of a field the page did not ask for shows "—", never its
 * last value and never a missing array.
 */
const BLANK_FRAME: Readonly<Record<string, unknown>> = Object.fromEntries(
  (LAYOUT.assemblies.find((a) => a.direction === "T2O")?.fields ?? []).map((f: FieldInfo) => [f.name, f.scalar || f.element_names !== undefined ? null : new Array<null>(f.count).fill(null)]),
);

/** `frame` as received, or, when it carries only some fields, with the others unknown. */
export function completeFrame(frame: Frame, fields: readonly string[] | null): Frame {
  return fields === null ? frame : ({ ...BLANK_FRAME, ...frame } as Frame);
}

/** Whether the robot state or any flag differs between two frames (null: no frame before). */
export function signalsChanged(before: Frame | null, after: Frame): boolean {
  if (before === null) return true;
  if (before.robot_state !== after.robot_state) return true;
  return FLAG_NAMES.some((name) => before[name] !== after[name]);
}

export class LiveData {
  readonly channels: ChannelMap;
  readonly ring: SampleRing;
  private readonly now: () => number;
  private readonly publishInterval_ms: number;
  private readonly row: Float64Array;
  private readonly listeners = new Set<Listener>();
  private readonly startedAt_ms: number;
  private frame: Frame | null = null;
  private frameSeq: number | null = null;
  private frameTime_s: number | null = null;
  private frameArrival_ms: number | null = null;
  private lastSeq: number | null = null;
  private socket: SocketState = "connecting";
  private connection: ConnectionStatus | null = null;
  private control: ControlStatus = { holder: null };
  private events: StreamEvent[] = [];
  private layoutMismatch: number | null = null;
  private rate_hz: number | null = null;
  /** The fields the frames carry (a subscription's; null: every field). */
  private fields: readonly string[] | null = null;
  private kiosk: KioskConfig | null = null;
  private staleSince_ms: number | null = null;
  private closeReason: string | null = null;
  /** A confirmed write's frame (`seq`), published the moment it is here (`showFrame`). */
  private awaitedSeq: number | null = null;
  private robot: string | null = null;
  private alarms: readonly Alarm[] = [];
  private session: string | null = null;
  private cellAlarms: CellAlarmSummary | null = null;
  private current: LiveSnapshot;
  /** When the snapshot was last published (the `now` clock, ms). */
  private publishedAt_ms = -Infinity;
  private timer: ReturnType<typeof setInterval> | null = null;
  framesReceived = 0;
  clientGaps = 0;
  dropped = 0;

  constructor(plots: readonly PlotSpec[], options: LiveDataOptions = {}) {
    this.channels = new ChannelMap(plots);
    this.ring = new SampleRing(options.capacity ?? RING_CAPACITY, this.channels.channelCount);
    this.row = new Float64Array(this.channels.channelCount);
    this.now = options.now ?? Date.now;
    this.publishInterval_ms = options.publishInterval_ms ?? PUBLISH_INTERVAL_MS;
    this.startedAt_ms = this.now();
    this.current = this.build();
  }

  /**
   * Republish on a timer too (frame age and health move with time even without messages): when
   * no beat has republished for two intervals (a hidden page's animation frames stop).
   */
  start(): void {
    if (this.timer !== null) return;
    this.timer = setInterval(() => {
      if (this.now() - this.publishedAt_ms >= 2 * this.publishInterval_ms) this.publish();
    }, this.publishInterval_ms);
  }

  /** The page's beat (lib/plots/plotCoordinator.ts `onBeat`): republish when the last is an interval old. */
  beat(): void {
    if (this.now() - this.publishedAt_ms >= this.publishInterval_ms) this.publish();
  }

  /**
   * A write was confirmed by the frame `seq` (its answer names it): show that frame the moment it
   * is here, not at the next periodic publish (up to `publishInterval_ms` later), so what the page
   * shows after "confirmed" is the robot's frame that confirmed it: the analog outputs, a preset's
   * values and everything else the frame carries.
   */
  showFrame(seq: number): void {
    if (this.lastSeq !== null && this.lastSeq >= seq) {
      this.awaitedSeq = null;
      this.publish();
    } else this.awaitedSeq = seq;
  }

  stop(): void {
    if (this.timer !== null) clearInterval(this.timer);
    this.timer = null;
  }

  subscribe = (listener: Listener): (() => void) => {
    this.listeners.add(listener);
    return () => {
      this.listeners.delete(listener);
    };
  };

  getSnapshot = (): LiveSnapshot => this.current;

  /**
   * The newest frame as received, between snapshots: for views that write the DOM themselves at
   * the data's own rate (the numeric readouts) without a React render per frame.
   */
  latestFrame(): Frame | null {
    return this.frame;
  }

  setSocketState(state: SocketState): void {
    if (state === this.socket) return;
    this.socket = state;
    if (state === "open") this.lastSeq = null; // a new socket starts its own sequence view
    this.publish();
  }

  setCloseReason(reason: string | null): void {
    if (reason === this.closeReason) return;
    this.closeReason = reason;
    this.publish();
  }

  handle(message: ServerMessage): void {
    switch (message.type) {
      case "hello":
        this.connection = message.connection;
        this.control = message.control;
        this.rate_hz = message.rate_hz;
        this.fields = null;
        this.kiosk = message.kiosk ?? null;
        this.robot = message.robot ?? null;
        // Every time on the page is the plant's (lib/common/dates.ts), as the service names it.
        setSiteTimeZone(message.time_zone);
        this.alarms = alarmsFromHello(message.alarms);
        this.session = message.session ?? null;
        this.cellAlarms = message.cell_alarms ?? null;
        this.layoutMismatch = message.layout_version === LAYOUT_VERSION ? null : message.layout_version;
        this.lastSeq = null;
        this.publish();
        return;
      case "frames": {
        const before = this.frame;
        for (const stamped of message.frames) this.addFrame(stamped.seq, stamped.t, completeFrame(stamped.frame, this.fields));
        if (this.awaitedSeq !== null && this.lastSeq !== null && this.lastSeq >= this.awaitedSeq) {
          // A confirmed write's frame came: shown at once (`showFrame`).
          this.awaitedSeq = null;
          this.publish();
          return;
        }
        // A state or flag change is shown at once, not at the next periodic publish.
        if (this.frame !== null && before !== this.frame && signalsChanged(before, this.frame)) this.publish();
        return;
      }
      case "dropped":
        this.dropped += message.count;
        return;
      case "status":
        this.connection = message.connection;
        if (message.cell_alarms !== undefined && message.cell_alarms !== null) this.cellAlarms = message.cell_alarms;
        this.publish();
        return;
      case "event":
        this.addEvent(message.event);
        this.publish();
        return;
      case "subscribed":
        // The frames after it are at this rate (their sequence jumps by design) and carry these
        // fields only; a field not asked for is not shown as its last value.
        this.rate_hz = message.rate_hz;
        this.fields = message.fields ?? null;
        this.lastSeq = null;
        this.publish();
        return;
    }
  }

  /** Control changes learnt from a REST answer (take/release) before the event arrives. */
  setControl(control: ControlStatus): void {
    this.control = control;
    this.publish();
  }

  private addFrame(seq: number, t_s: number, frame: Frame): void {
    // With a decimated stream (?rate=) the backend's sequence jumps by design: not a gap.
    if (this.rate_hz === null && this.lastSeq !== null && seq > this.lastSeq + 1) {
      this.clientGaps += seq - this.lastSeq - 1;
    }
    if (this.lastSeq === null || seq > this.lastSeq) this.lastSeq = seq;
    this.framesReceived++;
    this.frame = frame;
    this.frameSeq = seq;
    this.frameTime_s = t_s;
    this.frameArrival_ms = this.now();
    const row = this.row;
    row.fill(Number.NaN);
    for (const [field, base] of this.channels.base) {
      const values = frame[field];
      if (!Array.isArray(values)) continue;
      for (let i = 0; i < values.length; i++) {
        const v: unknown = values[i];
        row[base + i] = typeof v === "number" ? v : Number.NaN;
      }
    }
    this.ring.push(t_s * 1000, row);
  }

  private addEvent(event: StreamEvent): void {
    this.events = [event, ...this.events.slice(0, EVENT_LIMIT - 1)];
    if (event.kind === "control") this.control = { holder: event.holder };
    if (event.kind === "alarm") this.alarms = applyAlarm(this.alarms, event.alarm);
    if (event.kind === "connection" && this.connection !== null) {
      // The event is immediate; the next status (≤ 1 s) brings the rest.
      this.connection = { ...this.connection, state: event.state, reason: event.reason ?? null };
    }
  }

  /** Rebuild the snapshot and tell React. */
  publish(): void {
    this.publishedAt_ms = this.now();
    this.current = this.build();
    for (const listener of this.listeners) listener();
  }

  private build(): LiveSnapshot {
    const now = this.now();
    const frameAge_ms = this.frameArrival_ms === null ? null : now - this.frameArrival_ms;
    const health = connectionHealth({
      socket: this.socket,
      connection: this.connection,
      frameAge_ms,
    });
    if (health === "connected") {
      this.staleSince_ms = null;
    } else if (this.staleSince_ms === null) {
      this.staleSince_ms = this.frameArrival_ms ?? this.startedAt_ms;
    }
    return {
      frame: this.frame,
      frameSeq: this.frameSeq,
      frameTime_s: this.frameTime_s,
      frameAge_ms,
      socket: this.socket,
      connection: this.connection,
      control: this.control,
      health,
      staleSince_ms: this.staleSince_ms,
      framesReceived: this.framesReceived,
      clientGaps: this.clientGaps,
      dropped: this.dropped,
      events: this.events,
      layoutMismatch: this.layoutMismatch,
      rate_hz: this.rate_hz,
      fields: this.fields,
      kiosk: this.kiosk,
      closeReason: this.closeReason,
      robot: this.robot,
      alarms: this.alarms,
      session: this.session,
      cellAlarms: this.cellAlarms,
    };
  }
}
