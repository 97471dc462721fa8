import { describe, expect, it } from "vitest";
import type { KnockEvent } from "./healthTypes";
import { axisY, knockCountsWords, knockPicture, knockWords } from "./knocks";

const KNOCK: KnockEvent = { time: 1_765_000_000, kind: "collision", joint: 3, external_torque_nm: -42.04, joint_position_deg: [0, 90, -160, 180, 0, -360] };

describe("the knocks' joint-space picture", () => {
  it("puts +limit at the top of an axis, −limit at the bottom, 0 half-way, and clamps what is beyond", () => {
    expect(axisY(160, 160, 20, 220)).toBe(20);
    expect(axisY(-160, 160, 20, 220)).toBe(220);
    expect(axisY(0, 160, 20, 220)).toBe(120);
    expect(axisY(400, 360, 20, 220)).toBe(20);
  });

  it("draws a knock as a line through the arm's six positions, one axis per joint, J1 on the left", () => {
    const picture = knockPicture([KNOCK], [360, 360, 160, 360, 360, 360], 600, 260);
    expect(picture.axes.map((a) => a.joint)).toEqual([1, 2, 3, 4, 5, 6]);
    expect(picture.axes[0]?.x).toBe(48);
    expect(picture.axes[5]?.x).toBe(560);
    const points = (picture.lines[0]?.points ?? "").split(" ").map((p) => p.split(",").map(Number));
    expect(points).toHaveLength(6);
    const middle = (picture.top + picture.bottom) / 2;
    expect(points[0]?.[1]).toBeCloseTo(middle, 1); // J1 at 0°
    expect(points[2]?.[1]).toBeCloseTo(picture.bottom, 1); // J3 at −160° of ±160°
    expect(points[3]?.[1]).toBeCloseTo((picture.top + middle) / 2, 1); // J4 at +180° of ±360°
    expect(points[5]?.[1]).toBeCloseTo(picture.bottom, 1); // J6 at −360°
    expect(picture.lines[0]?.colour).toBe("#b71c1c");
  });

  it("leaves out a position that is not a number rather than drawing it at 0", () => {
    const picture = knockPicture([{ ...KNOCK, joint_position_deg: [0, 0, Number.NaN] }], [360, 360, 160, 360, 360, 360]);
    expect(picture.lines[0]?.points.split(" ")).toHaveLength(2);
  });

  it("says what a knock was and this shift's counts", () => {
    expect(knockWords(KNOCK)).toBe("external-torque peak on J3, 42.0 N·m");
    expect(knockWords({ kind: "protective_stop", joint: null, external_torque_nm: null })).toBe("protective stop");
    expect(knockCountsWords({ shift_start: 0, collisions: [0, 0, 2, 0, 1, 0], protective_stop: 1, emergency_stop: 0, servo_off: 2, events: [] })).toBe(
      "3 external-torque peaks (J3: 2, J5: 1), 1 protective stop, 2 servo offs",
    );
    expect(knockCountsWords({ shift_start: 0, collisions: [0, 0, 0, 0, 0, 0], protective_stop: 0, emergency_stop: 0, servo_off: 0, events: [] })).toBe("none this shift");
    expect(knockCountsWords(null)).toBe("not known");
  });
});
