/**
 * Layer: pure kiosk layout (no React, no DOM, no network): how the kiosk fills its screen
 * without scrolling.
 *
 * The kiosk is designed at 1920 × 1080 (landscape) or 1080 × 1920 (portrait) "design pixels";
 * `kioskScale` gives the factor `u` from those to the screen's pixels, so a 1280 × 720 screen
 * shows the same page at two thirds and a 3840 × 2160 one at twice the size. Every fixed size of
 * the kiosk (its CSS) is a multiple of `u`. Below the header, the body (tiles, plots, the 3D view)
 * is laid out here from the room it has, measured by the page: `bodyLayout` splits it into areas
 * and `tileGrid` computes the tiles' arrangement and font sizes, so any number of tiles fits
 * whatever the screen, without dropping one. Sizes are estimated from the text's length in
 * characters with the wide fonts' widths (DejaVu Sans, Chromium's default on Debian), on the safe
 * side.
 */

/** The design screens, in design pixels. */
export const DESIGN_LANDSCAPE = { width_px: 1920, height_px: 1080 } as const;
export const DESIGN_PORTRAIT = { width_px: 1080, height_px: 1920 } as const;

export interface KioskScale {
  /** Screen pixels per design pixel. */
  readonly u: number;
  readonly landscape: boolean;
}

/** The scale of a `width_px` × `height_px` viewport (a square one counts as landscape). */
export function kioskScale(width_px: number, height_px: number): KioskScale {
  const landscape = width_px >= height_px;
  const design = landscape ? DESIGN_LANDSCAPE : DESIGN_PORTRAIT;
  const u = Math.min(width_px / design.width_px, height_px / design.height_px);
  return { u: Number.isFinite(u) && u > 0 ? u : 1, landscape };
}

/** Text sizes of the kiosk at u = 1 (design pixels). */
export const KIOSK_TEXT = {
  /** The robot's name, the alarm banner, the emergency stop's words. */
  large_px: 48,
  /** The state badge never goes below this (it grows to the room it has). */
  stateMin_px: 56,
  /** Everything else: flags, connection, control, labels, titles, lamps' numbers, plots. */
  small_px: 24,
  /** The tiles' values aim at this and never go below `large_px` at u = 1 when there is room. */
  tileTarget_px: 64,
  /** Lamps' lights (diameter). */
  lamp_px: 32,
} as const;

/** Widths of characters in em (bold digits with the minus sign and point, labels, titles). */
const VALUE_EM_PER_CHAR = 0.68;
const LABEL_EM_PER_CHAR = 0.64;
const TITLE_EM_PER_CHAR = 0.64;

/** The tiles' box model in design pixels (scaled by u), as kioskTiles.css draws them. */
export const TILE_BOX = {
  gap: 12,
  padX: 12,
  padY: 10,
  cellGapX: 12,
  cellGapY: 4,
  /** Between a label and its value when side by side. */
  labelGap: 10,
  titleGap: 4,
} as const;
/** 1.2: the fonts' ascent and descent (DejaVu Sans: 1.164 em) fit inside a line; at 1.1 they spilled out of a cell. */
const VALUE_LINE = 1.2;
const LABEL_LINE = 1.2;
const TITLE_LINE = 1.2;

/** One tile as far as its size goes: its cells and the longest texts in them. */
export interface TileShape {
  readonly cells: number;
  /** Characters of the longest value it shows ("−1234.5": 7). */
  readonly valueChars: number;
  /** Characters of the longest channel label ("J 1": 3). */
  readonly labelChars: number;
  /** Characters of its title with the unit ("Joint 1–6 position [degree]"). */
  readonly titleChars: number;
}

/** How the tiles are arranged and how large their text is. */
export interface TileGrid {
  /** Tiles per row. */
  readonly columns: number;
  /** Cells per row inside a tile (a tile with fewer cells uses its own count). */
  readonly cellColumns: number;
  /** Labels above their values: always (issue 38; kept for the page's class). */
  readonly stacked: boolean;
  readonly value_px: number;
  readonly label_px: number;
  readonly title_px: number;
  /** The height the tiles take at these sizes (px, ≤ the area's). */
  readonly height_px: number;
}

interface Arrangement {
  readonly columns: number;
  readonly cellColumns: number;
  readonly stacked: boolean;
}

/** The labels' and titles' size for a value size: half of it, never under the small text. */
function labelSize(value_px: number, u: number): number {
  return Math.min(Math.max(KIOSK_TEXT.small_px * u, value_px * 0.45), 36 * u);
}

/**
 * The height (px) `tiles` take in `width_px` arranged as `a` with values of `value_px`, or
 * Infinity when something does not fit across.
 */
function heightOf(tiles: readonly TileShape[], width_px: number, a: Arrangement, value_px: number, u: number): number {
  if (tiles.length === 0) return 0;
  const label_px = labelSize(value_px, u);
  const title_px = label_px;
  const tileWidth = (width_px - (a.columns - 1) * TILE_BOX.gap * u) / a.columns;
  const innerWidth = tileWidth - 2 * TILE_BOX.padX * u - 2;
  if (innerWidth <= 0) return Infinity;
  let total = 0;
  for (let start = 0; start < tiles.length; start += a.columns) {
    let rowHeight = 0;
    for (const tile of tiles.slice(start, start + a.columns)) {
      const cols = Math.max(1, Math.min(a.cellColumns, tile.cells));
      const cellWidth = (innerWidth - (cols - 1) * TILE_BOX.cellGapX * u) / cols;
      const valueWidth = tile.valueChars * VALUE_EM_PER_CHAR * value_px;
      const labelWidth = tile.labelChars * LABEL_EM_PER_CHAR * label_px;
      const across = a.stacked ? Math.max(valueWidth, labelWidth) : labelWidth + TILE_BOX.labelGap * u + valueWidth;
      if (across > cellWidth) return Infinity;
      const rows = Math.ceil(tile.cells / cols);
      const cellHeight = a.stacked ? LABEL_LINE * label_px + VALUE_LINE * value_px : Math.max(VALUE_LINE * value_px, LABEL_LINE * label_px);
      const titleLines = Math.max(1, Math.ceil((tile.titleChars * TITLE_EM_PER_CHAR * title_px) / innerWidth));
      const height =
        2 * TILE_BOX.padY * u + 2 + titleLines * TITLE_LINE * title_px + TILE_BOX.titleGap * u + rows * cellHeight + (rows - 1) * TILE_BOX.cellGapY * u;
      rowHeight = Math.max(rowHeight, height);
    }
    total += rowHeight + (start > 0 ? TILE_BOX.gap * u : 0);
  }
  return total;
}

function arrangements(tiles: readonly TileShape[]): Arrangement[] {
  const most = Math.max(1, ...tiles.map((t) => t.cells));
  const out: Arrangement[] = [];
  for (let columns = 1; columns <= Math.max(1, tiles.length); columns++) {
    for (let cellColumns = 1; cellColumns <= most; cellColumns++) {
      // Labels above their values only: beside them a value sat nearer the next label than its own.
      out.push({ columns, cellColumns, stacked: true });
    }
  }
  return out;
}

/** The largest value size (px, to 0.5 px) at which `fits` holds, between `low` and `high`. */
function largest(fits: (value_px: number) => boolean, low: number, high: number): number {
  if (!fits(low)) return 0;
  if (fits(high)) return high;
  let lo = low;
  let hi = high;
  while (hi - lo > 0.5) {
    const mid = (lo + hi) / 2;
    if (fits(mid)) lo = mid;
    else hi = mid;
  }
  return lo;
}

/** The smallest value size the tiles are ever drawn at (px at u = 1): below it, scale down. */
export const TILE_VALUE_FLOOR_PX = 20;
/** Values never grow past this (px at u = 1): a single tile on a large screen stays a tile. */
export const TILE_VALUE_CAP_PX = 120;

/**
 * The arrangement of `tiles` in a `width_px` × `height_px` area with the largest values that
 * fit (at most `TILE_VALUE_CAP_PX`·u); null when even `TILE_VALUE_FLOOR_PX`·u does not fit.
 * Among arrangements that reach the cap, the one with the fewest rows of tiles.
 */
export function tileGrid(tiles: readonly TileShape[], width_px: number, height_px: number, u: number): TileGrid | null {
  if (tiles.length === 0) return { columns: 1, cellColumns: 1, stacked: true, value_px: KIOSK_TEXT.tileTarget_px * u, label_px: KIOSK_TEXT.small_px * u, title_px: KIOSK_TEXT.small_px * u, height_px: 0 };
  let best: { a: Arrangement; value_px: number } | null = null;
  const cap = TILE_VALUE_CAP_PX * u;
  for (const a of arrangements(tiles)) {
    const value_px = largest((v) => heightOf(tiles, width_px, a, v, u) <= height_px, TILE_VALUE_FLOOR_PX * u, cap);
    if (value_px <= 0) continue;
    if (best === null || value_px > best.value_px + 0.5) best = { a, value_px };
  }
  if (best === null) return null;
  const value_px = Math.floor(best.value_px);
  const label_px = Math.round(labelSize(value_px, u) * 10) / 10;
  return {
    ...best.a,
    value_px,
    label_px,
    title_px: label_px,
    height_px: Math.ceil(heightOf(tiles, width_px, best.a, value_px, u)),
  };
}

/** The least height (px) `tiles` need in `width_px` for values of `value_px` (Infinity: never). */
export function tilesHeightFor(tiles: readonly TileShape[], width_px: number, value_px: number, u: number): number {
  let least = Infinity;
  for (const a of arrangements(tiles)) least = Math.min(least, heightOf(tiles, width_px, a, value_px, u));
  return least;
}

/** What the body shows. */
export interface BodyContent {
  readonly tiles: readonly TileShape[];
  /** A line under the tiles naming tiles the robot does not report. */
  readonly unknownLine: boolean;
  readonly robot3d: boolean;
  /** Live plots (each a slot of its own). */
  readonly plots: number;
}

export interface Box {
  readonly width_px: number;
  readonly height_px: number;
}

/** The body's areas: a CSS grid, and the size of each area. */
export interface BodyLayout {
  readonly columns: string;
  readonly rows: string;
  readonly areas: string;
  /** The tiles' area and their grid (null: they do not fit even at the floor size). */
  readonly tiles: Box;
  readonly tileGrid: TileGrid | null;
  /** Each plot's slot. */
  readonly plot: Box;
  /** Plots side by side (else one above the other). */
  readonly plotsAcross: boolean;
  readonly robot3d: Box | null;
  /** Everything fits at this scale with the tiles at or above the floor and the plots at their least. */
  readonly fits: boolean;
}

/** Between the body's areas (design px). */
export const BODY_GAP = 12;
/** A plot's slot is never lower than this (design px): its title, legend and a plotting area. */
export const PLOT_MIN_HEIGHT = 220;
/** The plots' slots get this much (design px) before the tiles grow past the large size. */
export const PLOT_PREFERRED_HEIGHT = 320;
/** Plots sit side by side only when each gets at least this width (design px). */
export const PLOT_MIN_WIDTH = 480;
/** The 3D view's least height (design px). */
export const ROBOT3D_MIN_HEIGHT = 240;
/** The unknown tiles' line (design px: a line of small text and the grid's gap above it). */
const UNKNOWN_LINE = 42;

const px = (n: number) => `${Math.max(0, Math.floor(n))}px`;

/**
 * The tiles' height in a column `width` wide and `height` high above `plotRows` rows of plots:
 * what their target size needs, but no more than leaves the plots their preferred height while
 * the tiles still reach the large size, and never so much that the plots get less than their
 * least.
 */
function tilesHeight(need: (width: number, value_px: number) => number, width: number, height: number, plotRows: number, gap: number, u: number): number {
  if (plotRows === 0) return Math.max(0, Math.min(need(width, KIOSK_TEXT.tileTarget_px), height));
  const plotsGaps = plotRows * gap; // between the tiles and the plots, and between plot rows
  const most = height - plotRows * PLOT_MIN_HEIGHT * u - plotsGaps;
  const leavingPreferred = Math.max(need(width, KIOSK_TEXT.large_px), height - plotRows * PLOT_PREFERRED_HEIGHT * u - plotsGaps);
  return Math.max(0, Math.min(need(width, KIOSK_TEXT.tileTarget_px), leavingPreferred, most));
}

/**
 * The body's layout in a `body` box (what the header, banners and lamps leave): in landscape
 * the 3D view (if shown) takes a column on the right, the tiles the top of the rest and the
 * plots below them; in portrait everything is one column. The tiles get the height their
 * target size needs (or what the plots leave them), the plots the rest.
 */
export function bodyLayout(body: Box, content: BodyContent, scale: KioskScale): BodyLayout {
  const { u } = scale;
  const gap = BODY_GAP * u;
  const W = Math.max(0, body.width_px);
  const H = Math.max(0, body.height_px);
  const unknown = content.unknownLine ? UNKNOWN_LINE * u : 0;
  const hasTiles = content.tiles.length > 0 || content.unknownLine;
  const tilesNeed = (width: number, value: number) => (content.tiles.length > 0 ? tilesHeightFor(content.tiles, width, value * u, u) : 0) + unknown;
  const plots = Math.max(0, content.plots);

  if (scale.landscape) {
    const side = content.robot3d ? Math.round(Math.min(W * 0.3, H * 1.25)) : 0;
    const mainW = W - side - (content.robot3d ? gap : 0);
    const plotsAcross = plots > 1 && (mainW - (plots - 1) * gap) / plots >= PLOT_MIN_WIDTH * u;
    const plotsMin = plots === 0 ? 0 : plotsAcross ? PLOT_MIN_HEIGHT * u : plots * PLOT_MIN_HEIGHT * u + (plots - 1) * gap;
    const tilesRoom = hasTiles ? tilesHeight(tilesNeed, mainW, H, plots > 0 ? (plotsAcross ? 1 : plots) : 0, gap, u) : 0;
    const grid = tileGrid(content.tiles, mainW, tilesRoom - unknown, u);
    // The tiles' row as high as their text turned out (the plots get what a narrow tile leaves).
    const tilesH = grid !== null && hasTiles ? Math.min(tilesRoom, Math.ceil(grid.height_px + unknown)) : tilesRoom;
    const plotsH = H - tilesH - (hasTiles && plots > 0 ? gap : 0);
    const plot: Box = plotsAcross
      ? { width_px: (mainW - (plots - 1) * gap) / plots, height_px: plotsH }
      : { width_px: mainW, height_px: plots > 0 ? (plotsH - (plots - 1) * gap) / plots : 0 };
    const mainAreas = [hasTiles ? "tiles" : null, plots > 0 ? "plots" : null].filter((a): a is string => a !== null);
    const rows = [hasTiles ? px(tilesH) : null, plots > 0 ? "minmax(0, 1fr)" : null].filter((r): r is string => r !== null);
    const areas = (mainAreas.length > 0 ? mainAreas : ["plots"]).map((a) => `"${a}${content.robot3d ? " robot3d" : ""}"`).join(" ");
    return {
      columns: content.robot3d ? `minmax(0, 1fr) ${px(side)}` : "minmax(0, 1fr)",
      rows: rows.length > 0 ? rows.join(" ") : "minmax(0, 1fr)",
      areas,
      tiles: { width_px: mainW, height_px: tilesH },
      tileGrid: grid,
      plot,
      plotsAcross,
      robot3d: content.robot3d ? { width_px: side, height_px: H } : null,
      fits: (content.tiles.length === 0 || grid !== null) && plotsH + 0.5 >= plotsMin && (!content.robot3d || H >= ROBOT3D_MIN_HEIGHT * u),
    };
  }

  // Portrait: one column (tiles, 3D view, plots).
  const plotsAcross = plots > 1 && (W - (plots - 1) * gap) / plots >= PLOT_MIN_WIDTH * u;
  const plotsMin = plots === 0 ? 0 : plotsAcross ? PLOT_MIN_HEIGHT * u : plots * PLOT_MIN_HEIGHT * u + (plots - 1) * gap;
  const view3dMin = content.robot3d ? ROBOT3D_MIN_HEIGHT * u : 0;
  const gaps = gap * ([hasTiles, content.robot3d, plots > 0].filter(Boolean).length - 1);
  const tilesRoom = hasTiles ? tilesHeight(tilesNeed, W, H - view3dMin - (content.robot3d ? gap : 0), plots > 0 ? (plotsAcross ? 1 : plots) : 0, gap, u) : 0;
  const grid = tileGrid(content.tiles, W, tilesRoom - unknown, u);
  const tilesH = grid !== null && hasTiles ? Math.min(tilesRoom, Math.ceil(grid.height_px + unknown)) : tilesRoom;
  const rest = H - tilesH - Math.max(0, gaps);
  // What the tiles leave: the 3D view a third of it (at least its least), the plots the others.
  const view3dH = content.robot3d ? Math.max(view3dMin, plots > 0 ? rest / 3 : rest) : 0;
  const plotsH = rest - view3dH;
  const plot: Box = plotsAcross
    ? { width_px: (W - (plots - 1) * gap) / plots, height_px: plotsH }
    : { width_px: W, height_px: plots > 0 ? (plotsH - (plots - 1) * gap) / plots : 0 };
  const order: [string, string | null][] = [
    ["tiles", hasTiles ? px(tilesH) : null],
    ["robot3d", content.robot3d ? px(view3dH) : null],
    ["plots", plots > 0 ? "minmax(0, 1fr)" : null],
  ];
  const shown = order.filter((entry): entry is [string, string] => entry[1] !== null);
  return {
    columns: "minmax(0, 1fr)",
    rows: shown.map(([, size]) => size).join(" ") || "minmax(0, 1fr)",
    areas: shown.map(([name]) => `"${name}"`).join(" ") || '"plots"',
    tiles: { width_px: W, height_px: tilesH },
    tileGrid: grid,
    plot,
    plotsAcross,
    robot3d: content.robot3d ? { width_px: W, height_px: view3dH } : null,
    fits: (content.tiles.length === 0 || grid !== null) && plotsH + 0.5 >= plotsMin,
  };
}

/** The kiosk's plots' window without a word from the service (an older one): 30 s, a cycle. */
export const DEFAULT_KIOSK_PLOT_WINDOW_MS = 30_000;

/**
 * The kiosk's plots' window (ms) from the service's `kiosk_plot_window_s` setting (the stream's
 * hello): long enough for at least one of the robot's cycles, not the panel's 10 s.
 */
export function kioskPlotWindow_ms(config: { readonly plot_window_s: number } | null): number {
  const window_s = config?.plot_window_s;
  return window_s !== undefined && Number.isFinite(window_s) && window_s > 0 ? window_s * 1000 : DEFAULT_KIOSK_PLOT_WINDOW_MS;
}
