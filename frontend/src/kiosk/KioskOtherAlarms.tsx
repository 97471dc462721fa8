/**
 * The kiosk's line for each other robot with a critical or unacknowledged alarm
 * (lib/kiosk/kioskOtherAlarms.ts), under its own banner: read-only, large enough to read from three
 * metres (never under 32 px on a 1080-line screen), in the alarm's pendant colour.
 */
import { alarmPaint } from "../lib/alarms/alarms";
import type { KioskOtherLine } from "../lib/kiosk/kioskOtherAlarms";
import "../styles/kioskOtherAlarms.css";

export function KioskOtherAlarms({ lines }: { readonly lines: readonly KioskOtherLine[] }) {
  if (lines.length === 0) return null;
  return (
    <ul className="kiosk-other-alarms" aria-label="Other robots' alarms">
      {lines.map((line) => {
        const paint = alarmPaint(line.colour);
        return (
          <li
            key={line.robot}
            className={`kiosk-other-alarm${line.unacknowledged ? " is-unacknowledged" : ""}`}
            data-testid="kiosk-other-alarm"
            data-robot={line.robot}
            data-priority={line.priority}
            role="alert"
            style={{ background: paint.background, color: paint.text }}
          >
            {line.text}
          </li>
        );
      })}
    </ul>
  );
}
