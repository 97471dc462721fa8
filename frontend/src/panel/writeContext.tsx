/**
 * Layer: React glue for writing (panel only; the kiosk never imports this).
 *
 * Holds the logged-in user, the command image being sent (polled from the API), the write
 * tracker, the "confirm register writes" setting and the confirmation dialog, and decides
 * whether writing is possible at all (operator role, control held, live connection, not
 * read-only) — with the reason shown when it is not.
 */
import { createContext, useCallback, useContext, useEffect, useMemo, useRef, useState, useSyncExternalStore, type ReactNode } from "react";
import type { CommandPatch } from "../generated/layout";
import { api as rest } from "../lib/api/api";
import type { LiveSnapshot } from "../lib/stream/liveData";
import { RuntimeContext } from "../components/runtimeContext";
import { controlOwnership } from "../lib/writes/controlSession";
import { roleAtLeast, type CommandState, type User } from "../lib/api/protocol";
import { stopWarning } from "../lib/writes/writeChecks";
import { WriteTracker, performWrite, type WriteValue, type WriteView } from "../lib/writes/writes";
import { ConfirmDialog } from "../components/ConfirmDialog";

const CONFIRM_REGISTERS_KEY = "cobot-hmi.confirm-register-writes";
const COMMAND_POLL_MS = 2000;

export interface WriteApi {
  readonly tracker: WriteTracker;
  readonly user: User | null;
  readonly canWrite: boolean;
  readonly blockReason: string | null;
  readonly command: CommandState | null;
  readonly confirmRegisters: boolean;
  setConfirmRegisters(on: boolean): void;
  /** Ask (if `confirmMessage`), then PATCH `patch`, tracking `keys` ← `values`. */
  write(keys: readonly string[], values: readonly WriteValue[], patch: CommandPatch, confirmMessage: string | null): Promise<void>;
  refreshCommand(): void;
}

const WriteContext = createContext<WriteApi | null>(null);

export function useWrites(): WriteApi {
  const api = useContext(WriteContext);
  if (api === null) throw new Error("WriteContext missing");
  return api;
}

/** What a control shows for `key` given the robot's actual value; re-renders on write changes. */
export function useWriteView(key: string, actual: WriteValue | null | undefined): WriteView {
  const { tracker } = useWrites();
  useSyncExternalStore(tracker.subscribe, tracker.getVersion);
  return tracker.view(key, actual);
}

export function blockReasonOf(user: User | null, live: LiveSnapshot): string | null {
  if (user === null) return "Log in as an operator to write.";
  if (!roleAtLeast(user, "operator")) return `Your role (${user.role}) may not write.`;
  const ownership = controlOwnership(live.control, user, live.session);
  if (ownership !== "you") {
    if (ownership === "you-elsewhere") return "Control is held by you in another window: release it there and take it here to write.";
    return live.control.holder === null ? "Take control to write." : `${live.control.holder.user} holds control.`;
  }
  if (live.connection?.mode === "input_only") return "Read-only: the HMI listens beside a PLC (input only).";
  if (live.health !== "connected") return `Cannot write while ${live.health}.`;
  return null;
}

interface ConfirmRequest {
  readonly message: string;
  readonly resolve: (ok: boolean) => void;
}

function readSetting(): boolean {
  try {
    return window.localStorage.getItem(CONFIRM_REGISTERS_KEY) !== "false";
  } catch {
    return true;
  }
}

export function WriteProvider({
  robot,
  user,
  live,
  children,
}: {
  robot: string;
  user: User | null;
  live: LiveSnapshot;
  children: ReactNode;
}) {
  const tracker = useMemo(() => new WriteTracker(), []);
  // The page's live pipeline (null in a test without one): a confirmed write's frame is shown at once.
  const runtime = useContext(RuntimeContext);
  const [command, setCommand] = useState<CommandState | null>(null);
  const [confirmRegisters, setConfirmRegistersState] = useState(readSetting);
  const [confirm, setConfirm] = useState<ConfirmRequest | null>(null);
  const alive = useRef(true);

  const refreshCommand = useCallback(() => {
    rest
      .command(robot)
      .then((c) => {
        if (alive.current && c !== null) setCommand(c);
      })
      .catch(() => undefined);
  }, [robot]);

  useEffect(() => {
    alive.current = true;
    refreshCommand();
    const timer = setInterval(refreshCommand, COMMAND_POLL_MS);
    return () => {
      alive.current = false;
      clearInterval(timer);
    };
  }, [refreshCommand]);

  // The frame the display shows: a confirmed write is shown as written until it gets there.
  useEffect(() => {
    tracker.showing(live.frameSeq);
  }, [tracker, live.frameSeq]);

  // Someone's write (ours or another operator's) changes the image: fetch it at once.
  const newestEvent = live.events[0];
  useEffect(() => {
    if (newestEvent?.kind === "write" || newestEvent?.kind === "control") refreshCommand();
  }, [newestEvent, refreshCommand]);

  const setConfirmRegisters = useCallback((on: boolean) => {
    setConfirmRegistersState(on);
    try {
      window.localStorage.setItem(CONFIRM_REGISTERS_KEY, on ? "true" : "false");
    } catch {
      // storage unavailable: the setting lasts for this page only
    }
  }, []);

  const ask = useCallback(
    (message: string) => new Promise<boolean>((resolve) => setConfirm({ message, resolve })),
    [],
  );

  const write = useCallback(
    async (keys: readonly string[], values: readonly WriteValue[], patch: CommandPatch, confirmMessage: string | null) => {
      if (confirmMessage !== null && !(await ask(confirmMessage))) return;
      const outcome = await performWrite(tracker, keys, values, () => rest.patchCommand(robot, patch));
      // Everything the page shows comes from the confirming frame at once (lib/stream/liveData.ts).
      if (outcome.kind === "confirmed" && outcome.seq !== null) runtime?.live.showFrame(outcome.seq);
      refreshCommand();
    },
    [ask, tracker, refreshCommand, robot, runtime],
  );

  const blockReason = blockReasonOf(user, live);
  // Stable unless something a control shows changed: controls are memoized on it.
  const api: WriteApi = useMemo(
    () => ({
      tracker,
      user,
      canWrite: blockReason === null,
      blockReason,
      command,
      confirmRegisters,
      setConfirmRegisters,
      write,
      refreshCommand,
    }),
    [tracker, user, blockReason, command, confirmRegisters, setConfirmRegisters, write, refreshCommand],
  );

  const answer = (ok: boolean) => {
    confirm?.resolve(ok);
    setConfirm(null);
  };

  return (
    <WriteContext.Provider value={api}>
      {children}
      {confirm !== null && <ConfirmDialog message={confirm.message} warning={stopWarning(live.frame)} onAnswer={answer} />}
    </WriteContext.Provider>
  );
}
