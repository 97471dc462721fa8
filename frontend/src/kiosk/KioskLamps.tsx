/**
 * The kiosk's I/O lamps: each group named once ("DI", "Tool DO") with its lamps numbered after
 * it, so the 44 lamps of the control box and the tool take two lines of a 1920 px screen at a
 * size read from three metres. Tag names stay beside their lamp; the full label ("DI 3") and
 * the tag are each lamp's tooltip and the group's name is its accessible name.
 */
import type { Frame } from "../generated/layout";
import { Lamp } from "../components/Lamp";
import { useTagNames } from "../components/tagNames";
import { tagLabel } from "../lib/alarms/alarms";
import { channelNumber, frameField } from "../lib/layout/layoutInfo";

type LampField = "controlbox_di" | "controlbox_do" | "tool_di" | "tool_do";

/** The groups in the order shown: inputs on the first line, outputs on the second. */
const GROUPS: readonly { field: LampField; testPrefix: string }[] = [
  { field: "controlbox_di", testPrefix: "di" },
  { field: "tool_di", testPrefix: "tool-di" },
  { field: "controlbox_do", testPrefix: "do" },
  { field: "tool_do", testPrefix: "tool-do" },
];

/** "DI 1" → "DI", "Tool DO 6" → "Tool DO": a group's short name from its channels' labels. */
export function groupName(firstLabel: string): string {
  return firstLabel.replace(/\s*\d+$/, "");
}

function LampGroup({ field, testPrefix, frame }: { field: LampField; testPrefix: string; frame: Frame | null }) {
  const info = frameField(field);
  const values = frame?.[field] ?? null;
  const tags = useTagNames();
  return (
    <div className="kiosk-lamps__group" role="group" aria-label={info.description}>
      <span className="kiosk-lamps__name" aria-hidden="true">
        {groupName(info.channels[0] ?? field)}
      </span>
      {info.channels.map((label, i) => {
        const n = channelNumber(label);
        const tag = tags[`${field}.${i}`];
        return (
          <Lamp
            key={label}
            testId={`${testPrefix}-${n}`}
            label={String(n)}
            tag={tag}
            title={tagLabel(label, tag)}
            on={values === null ? null : (values[i] ?? null)}
          />
        );
      })}
    </div>
  );
}

export function KioskLamps({ frame }: { frame: Frame | null }) {
  return (
    // A landmark of its own, beside the header and the main one: nothing on the kiosk outside one.
    <section className="kiosk-lamps" data-testid="kiosk-lamps" aria-label="Inputs and outputs">
      {GROUPS.map((g) => [
        // Outputs start a line of their own.
        g.field === "controlbox_do" ? <span key="break" className="kiosk-lamps__break" aria-hidden="true" /> : null,
        <LampGroup key={g.field} field={g.field} testPrefix={g.testPrefix} frame={frame} />,
      ])}
    </section>
  );
}
