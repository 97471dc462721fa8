/**
 * The panel's session idle clock (lib/writes/sessionIdle.ts) while someone is logged in: the person's
 * clicks, keys and wheel turns anywhere on the page are reported to the service (which alone
 * renews the session), and when the session has idled out the page is told at once.
 */
import { useEffect, useRef } from "react";
import { api } from "../lib/api/api";
import { SessionIdleWatch } from "../lib/writes/sessionIdle";
import type { User } from "../lib/api/protocol";

/** What a person does; the page's own timers and requests are none of these. */
const PERSON_EVENTS = ["pointerdown", "keydown", "wheel"] as const;

export function useSessionIdle(user: User | null, onExpired: () => void): void {
  const expired = useRef(onExpired);
  useEffect(() => {
    expired.current = onExpired;
  }, [onExpired]);
  const name = user?.name ?? null;
  useEffect(() => {
    if (name === null) return;
    const watch = new SessionIdleWatch({
      report: () => api.activity(),
      check: () => api.session(),
      onExpired: () => expired.current(),
    });
    const acted = () => watch.personActed();
    for (const kind of PERSON_EVENTS) window.addEventListener(kind, acted, { capture: true, passive: true });
    watch.start();
    return () => {
      for (const kind of PERSON_EVENTS) window.removeEventListener(kind, acted, { capture: true });
      watch.stop();
    };
  }, [name]);
}
