import { describe, expect, it } from "vitest";
import { customPlot, isPickable, MAX_CUSTOM_PLOTS, PICKABLE_FIELDS, refuseNewPlot } from "./customPlots";
import { ChannelMap, axisTitles, tracesOf } from "./plots";

describe("custom plots", () => {
  it("offer every numeric field of the frame and nothing else", () => {
    const names = PICKABLE_FIELDS.map((f) => f.name);
    expect(names).toContain("joint_position");
    expect(names).toContain("analog_input");
    expect(names).toContain("external_moment");
    expect(names).not.toContain("servo_on");
    expect(names).not.toContain("controlbox_do");
    expect(isPickable("robot_state")).toBe(false);
  });

  it("plot a field of a robot with the layout's channels and unit", () => {
    const plot = customPlot("m0609", "joint_motor_temperature", 3);
    expect(plot.spec.id).toBe("plot-custom-3");
    expect(plot.spec.title).toBe("m0609 · Joint 1–6 motor temperature");
    expect(tracesOf(plot.spec)).toHaveLength(6);
    expect(axisTitles(plot.spec).y).toBe("motor temperature [°C]");
    // Its own ring buffers exactly that field.
    expect(new ChannelMap([plot.spec]).channelCount).toBe(6);
  });

  it("refuse what cannot be added, saying why", () => {
    const one = customPlot("a", "joint_torque", 1);
    expect(refuseNewPlot([], null, "joint_torque")).toMatch(/robot/);
    expect(refuseNewPlot([], "a", "")).toMatch(/signal/);
    expect(refuseNewPlot([], "a", "servo_on")).toMatch(/not a numeric/);
    expect(refuseNewPlot([one], "a", "joint_torque")).toMatch(/already/);
    expect(refuseNewPlot([one], "b", "joint_torque")).toBeNull();
    const full = Array.from({ length: MAX_CUSTOM_PLOTS }, (_, i) => customPlot("a", "joint_position", i));
    expect(refuseNewPlot(full, "b", "tcp_position")).toMatch(/At most/);
  });
});
