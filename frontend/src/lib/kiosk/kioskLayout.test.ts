import { describe, expect, it } from "vitest";
import { frameField } from "../layout/layoutInfo";
import { bodyLayout, KIOSK_TEXT, kioskScale, PLOT_MIN_HEIGHT, tileGrid, tilesHeightFor, TILE_VALUE_CAP_PX, type BodyContent } from "./kioskLayout";
import { tileShape } from "./kioskTiles";

const joints = tileShape(frameField("joint_position"));
const temperatures = tileShape(frameField("joint_motor_temperature"));
const tcp = tileShape(frameField("tcp_position"));

/** The body's room at 1920 × 1080 with an alarm and an emergency stop shown (as measured in Chromium). */
const BODY_ALARM_1080 = { width_px: 1892, height_px: 600 };

describe("kioskScale", () => {
  it("is 1 at 1920 × 1080 and follows 16:9 screens both ways", () => {
    expect(kioskScale(1920, 1080)).toEqual({ u: 1, landscape: true });
    expect(kioskScale(1280, 720).u).toBeCloseTo(2 / 3, 6);
    expect(kioskScale(3840, 2160).u).toBe(2);
  });

  it("takes the tighter side of other shapes, and portrait screens by their own design", () => {
    expect(kioskScale(1920, 1200).u).toBe(1); // wider than 16:9 is limited by the width… taller by the height
    expect(kioskScale(2560, 1080).u).toBe(1);
    expect(kioskScale(1080, 1920)).toEqual({ u: 1, landscape: false });
    expect(kioskScale(0, 0).u).toBe(1); // a window not laid out yet
  });
});

describe("tileShape", () => {
  it("gives each tile room for its longest value, label and title", () => {
    expect(joints).toEqual({ cells: 6, valueChars: 6, labelChars: 3, titleChars: "Joint 1–6 position".length + " [degree]".length });
    expect(tcp.cells).toBe(3);
    expect(tcp.valueChars).toBe(7); // −1234.5 mm
  });
});

describe("tileGrid", () => {
  it("fills the room it is given with the largest values that fit", () => {
    const grid = tileGrid([joints, temperatures], 1300, 260, 1);
    expect(grid).not.toBeNull();
    if (grid === null) return;
    expect(grid.value_px).toBeGreaterThanOrEqual(KIOSK_TEXT.large_px);
    expect(grid.label_px).toBeGreaterThanOrEqual(KIOSK_TEXT.small_px);
    expect(grid.height_px).toBeLessThanOrEqual(260);
    // One size larger would not fit.
    expect(tilesHeightFor([joints, temperatures], 1300, grid.value_px + 1, 1)).toBeGreaterThan(260);
  });

  it("grows its values with the room and caps them", () => {
    const small = tileGrid([joints], 900, 200, 1);
    const large = tileGrid([joints], 1800, 600, 1);
    const huge = tileGrid([joints], 8000, 8000, 1);
    expect(small?.value_px ?? 0).toBeLessThan(large?.value_px ?? 0);
    expect(huge?.value_px).toBe(TILE_VALUE_CAP_PX);
  });

  it("scales with u: the same arrangement at twice the size on a 4K screen", () => {
    const one = tileGrid([joints, tcp], 1300, 260, 1);
    const two = tileGrid([joints, tcp], 2600, 520, 2);
    expect(two?.columns).toBe(one?.columns);
    expect(two?.cellColumns).toBe(one?.cellColumns);
    expect(two?.value_px ?? 0).toBeGreaterThanOrEqual(2 * (one?.value_px ?? 0) - 1);
  });

  it("puts many tiles in rows and columns rather than dropping any, and says when nothing fits", () => {
    const many = Array.from({ length: 8 }, () => joints);
    const grid = tileGrid(many, 1892, 600, 1);
    expect(grid).not.toBeNull();
    expect((grid?.columns ?? 0) * Math.ceil(8 / (grid?.columns ?? 1))).toBeGreaterThanOrEqual(8);
    expect(grid?.height_px ?? Infinity).toBeLessThanOrEqual(600);
    expect(tileGrid(many, 300, 100, 1)).toBeNull();
  });

  it("takes no room without tiles", () => {
    expect(tileGrid([], 1000, 500, 1)?.height_px).toBe(0);
  });
});

describe("bodyLayout", () => {
  const content = (over: Partial<BodyContent>): BodyContent => ({ tiles: [joints, tcp], unknownLine: false, robot3d: false, plots: 2, ...over });

  it("at 1920 × 1080 with an alarm, tiles, the 3D view and two plots: values of 48 px and more, all within the body", () => {
    const layout = bodyLayout(BODY_ALARM_1080, content({ tiles: [joints, temperatures], robot3d: true }), { u: 1, landscape: true });
    expect(layout.fits).toBe(true);
    expect(layout.tileGrid?.value_px ?? 0).toBeGreaterThanOrEqual(48);
    expect(layout.robot3d?.width_px ?? 0).toBeGreaterThan(400);
    expect(layout.plot.height_px).toBeGreaterThanOrEqual(PLOT_MIN_HEIGHT);
    expect(layout.tiles.height_px + 12 + layout.plot.height_px).toBeLessThanOrEqual(BODY_ALARM_1080.height_px + 0.5);
    expect(layout.tiles.width_px + 12 + (layout.robot3d?.width_px ?? 0)).toBeLessThanOrEqual(BODY_ALARM_1080.width_px + 0.5);
    expect(layout.areas).toBe('"tiles robot3d" "plots robot3d"');
    expect(layout.plotsAcross).toBe(true);
  });

  it("without the 3D view the tiles and plots take the whole width", () => {
    const layout = bodyLayout({ width_px: 1892, height_px: 760 }, content({}), { u: 1, landscape: true });
    expect(layout.columns).toBe("minmax(0, 1fr)");
    expect(layout.areas).toBe('"tiles" "plots"');
    expect(layout.tiles.width_px).toBe(1892);
    expect(layout.tileGrid?.value_px ?? 0).toBeGreaterThanOrEqual(48);
    expect(layout.fits).toBe(true);
  });

  it("gives the plots what the tiles' text leaves, never less than their least", () => {
    const layout = bodyLayout({ width_px: 1892, height_px: 760 }, content({}), { u: 1, landscape: true });
    expect(layout.tiles.height_px).toBe(Math.ceil(layout.tileGrid?.height_px ?? NaN));
    expect(layout.plot.height_px).toBeCloseTo(760 - 12 - layout.tiles.height_px, 6);
  });

  it("does not fit a dozen tiles in a small body: the page scales down", () => {
    const many = Array.from({ length: 12 }, () => joints);
    expect(bodyLayout({ width_px: 1892, height_px: 300 }, content({ tiles: many, robot3d: true }), { u: 1, landscape: true }).fits).toBe(false);
    // At 0.6 of the scale the same room holds them.
    expect(bodyLayout({ width_px: 1892, height_px: 700 }, content({ tiles: many, robot3d: true }), { u: 0.6, landscape: true }).fits).toBe(true);
  });

  it("names tiles it cannot show in a line of their own", () => {
    const layout = bodyLayout({ width_px: 1892, height_px: 700 }, content({ tiles: [], unknownLine: true }), { u: 1, landscape: true });
    expect(layout.areas).toBe('"tiles" "plots"');
    expect(layout.tiles.height_px).toBeGreaterThan(0);
    expect(layout.tiles.height_px).toBeLessThan(60);
  });

  it("stacks everything in one column on a portrait screen", () => {
    const layout = bodyLayout({ width_px: 1052, height_px: 1400 }, content({ robot3d: true }), { u: 1, landscape: false });
    expect(layout.columns).toBe("minmax(0, 1fr)");
    expect(layout.areas).toBe('"tiles" "robot3d" "plots"');
    expect(layout.fits).toBe(true);
    expect(layout.plotsAcross).toBe(true);
    expect(layout.rows).toMatch(/^\d+px \d+px minmax\(0, 1fr\)$/);
  });
});

describe("tiles in every state (issue 38)", () => {
  it("put every label above its value, with an alarm's smaller body as without", () => {
    const content: BodyContent = { tiles: [joints, tcp], unknownLine: false, robot3d: false, plots: 2 };
    const quiet = bodyLayout({ width_px: 1892, height_px: 760 }, content, { u: 1, landscape: true });
    const alarm = bodyLayout(BODY_ALARM_1080, content, { u: 1, landscape: true });
    const small = bodyLayout({ width_px: 1252, height_px: 380 }, content, { u: 2 / 3, landscape: true });
    for (const layout of [quiet, alarm, small]) expect(layout.tileGrid?.stacked).toBe(true);
    for (const width of [300, 600, 1200, 2400]) for (const height of [120, 300, 900]) {
      const grid = tileGrid([joints, temperatures, tcp], width, height, width / 1920);
      if (grid !== null) expect(grid.stacked).toBe(true);
    }
  });
});
