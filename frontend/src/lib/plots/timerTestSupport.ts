/** A fake `Timer` (lib/plots/historyView.ts) for tests: callbacks wait in `due` until `fire()` runs them. */
import type { Timer } from "./historyView";

export function fakeTimer() {
  const due: { cb: () => void; handle: number; delay_ms: number }[] = [];
  let next = 0;
  const timer: Timer = {
    set: (cb, delay_ms) => {
      const handle = ++next;
      due.push({ cb, handle, delay_ms });
      return handle;
    },
    clear: (h) => {
      const i = due.findIndex((d) => d.handle === h);
      if (i >= 0) due.splice(i, 1);
    },
  };
  /** Runs every callback due now (those a callback sets wait for the next call). */
  const fire = () => due.splice(0).forEach((d) => d.cb());
  return { timer, fire, due };
}
