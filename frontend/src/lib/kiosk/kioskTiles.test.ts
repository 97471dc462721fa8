import { describe, expect, it } from "vitest";
import { LAYOUT, type Frame } from "../../generated/layout";
import { frameField } from "../layout/layoutInfo";
import { formatTileValue, plainName, stateWords, tileCells, tileDecimals, tilesFromSearch, TILE_FIELDS } from "./kioskTiles";

describe("tilesFromSearch", () => {
  it("takes the fields the URL names, in its order, once each", () => {
    const choice = tilesFromSearch("?robot=cell-1&tiles=tcp_position,joint_position,tcp_position");
    expect(choice.fields.map((f) => f.name)).toEqual(["tcp_position", "joint_position"]);
    expect(choice.unknown).toEqual([]);
  });

  it("reports names that are no numeric field", () => {
    const choice = tilesFromSearch("?tiles=joint_position,bogus,servo_on,robot_state");
    expect(choice.fields.map((f) => f.name)).toEqual(["joint_position"]);
    expect(choice.unknown).toEqual(["bogus", "servo_on", "robot_state"]);
  });

  it("adds up repeated parameters and ignores blanks", () => {
    const choice = tilesFromSearch("?tiles=joint_motor_temperature,&tiles=%20external_force%20");
    expect(choice.fields.map((f) => f.name)).toEqual(["joint_motor_temperature", "external_force"]);
  });

  it("shows joint and TCP positions when the URL chooses nothing", () => {
    expect(tilesFromSearch("?robot=a").fields.map((f) => f.name)).toEqual(["joint_position", "tcp_position"]);
  });

  it("offers only numbers", () => {
    expect(TILE_FIELDS.every((f) => f.value_kind !== "bool")).toBe(true);
    expect(TILE_FIELDS.map((f) => f.name)).toContain("analog_input");
  });
});

describe("formatTileValue", () => {
  const position = frameField("joint_position");
  it("uses fixed decimals per field and a real minus sign", () => {
    expect(formatTileValue(12.345, position)).toBe("12.3");
    expect(formatTileValue(-7.25, position)).toBe("\u22127.3");
    expect(formatTileValue(0, position)).toBe("0.0");
    expect(formatTileValue(-0.04, position)).toBe("0.0"); // no "−0.0"
  });

  it("shows a dash for no value", () => {
    expect(formatTileValue(null, position)).toBe("—");
    expect(formatTileValue(Number.NaN, position)).toBe("—");
    expect(formatTileValue(undefined, position)).toBe("—");
  });

  it("gives currents two decimals", () => {
    expect(tileDecimals(frameField("joint_motor_current"))).toBe(2); // unit A
    expect(formatTileValue(1.234, frameField("joint_motor_current"))).toBe("1.23");
  });
});

describe("tileCells", () => {
  it("labels each channel from the layout", () => {
    const field = frameField("tcp_position");
    const frame = { tcp_position: [466.94, 309.4, -0.01] } as unknown as Frame;
    const cells = tileCells(field, frame);
    expect(cells.map((c) => c.text)).toEqual(["466.9", "309.4", "0.0"]);
    expect(cells.map((c) => c.label)).toEqual(field.channels);
  });

  it("shows dashes before the first frame", () => {
    const cells = tileCells(frameField("joint_position"), null);
    expect(cells).toHaveLength(6);
    expect(cells.every((c) => c.text === "—")).toBe(true);
  });
});

describe("stateWords", () => {
  it("says the state in plain words from the layout", () => {
    expect(plainName("STANDALONE_RUNNING")).toBe("Standalone running");
    const words = stateWords(14);
    expect(words.title).toBe("Standalone running");
    expect(words.detail).toBe("Running its program");
  });

  it("says what a state means at the cell in a few words, never the manual's sentence (issue 38)", () => {
    expect(stateWords(13).detail).toBe("Ready, no program running");
    for (const state of LAYOUT.robot_states) {
      const { detail } = stateWords(state.value);
      expect(detail, state.name).not.toMatch(/Teach Pendant|mode execution screen|is displayed for/);
      expect(detail.split(" ").length, `${state.name}: ${detail}`).toBeLessThanOrEqual(9);
      expect(detail, state.name).not.toBe(state.description);
    }
  });

  it("says when there is no data or the value is unknown", () => {
    expect(stateWords(null).title).toBe("No data");
    expect(stateWords(999).title).toBe("Unknown state");
  });
});
