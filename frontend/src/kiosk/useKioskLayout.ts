/**
 * The kiosk's layout in the page: the scale from the window's size (lib/kiosk/kioskLayout.ts), the
 * body's room measured as the header and banners leave it, and the body's areas computed from
 * that room. Should even the least sizes not fit (a dozen tiles on a small screen), everything is
 * scaled down a step at a time until they do; a new window size or a change of what the header
 * shows (an alarm, an emergency stop) starts again from the full scale.
 */
import { useEffect, useLayoutEffect, useMemo, useState, type RefObject } from "react";
import { bodyLayout, kioskScale, type BodyContent, type BodyLayout, type Box } from "../lib/kiosk/kioskLayout";

/** The least share of the full scale the kiosk is ever shrunk to. */
const MIN_FIT = 0.4;
/** Each step down when something does not fit. */
const FIT_STEP = 0.9;

export interface KioskLayout {
  /** Screen pixels per design pixel, as the CSS's `--u`. */
  readonly u: number;
  readonly landscape: boolean;
  /** The body's areas (null until its room was measured). */
  readonly body: BodyLayout | null;
}

function useViewport(): { readonly width_px: number; readonly height_px: number } {
  const [viewport, setViewport] = useState(() => ({ width_px: window.innerWidth, height_px: window.innerHeight }));
  useEffect(() => {
    const onResize = () => setViewport({ width_px: window.innerWidth, height_px: window.innerHeight });
    window.addEventListener("resize", onResize);
    return () => window.removeEventListener("resize", onResize);
  }, []);
  return viewport;
}

/** The content box of `ref`'s element, followed as it changes (null before the first look). */
function useBoxOf(ref: RefObject<HTMLElement | null>): Box | null {
  const [box, setBox] = useState<Box | null>(null);
  useLayoutEffect(() => {
    const el = ref.current;
    if (el === null) return;
    const measure = () => {
      const width_px = el.clientWidth;
      const height_px = el.clientHeight;
      setBox((prev) => (prev !== null && prev.width_px === width_px && prev.height_px === height_px ? prev : { width_px, height_px }));
    };
    measure();
    if (typeof ResizeObserver === "undefined") return;
    const observer = new ResizeObserver(measure);
    observer.observe(el);
    return () => observer.disconnect();
  }, [ref]);
  return box;
}

/**
 * `content` must keep its identity while it stays the same (memoised by the caller);
 * `headerKey` names what the header and banners show, whose change may give the body more room.
 */
export function useKioskLayout(body: RefObject<HTMLElement | null>, content: BodyContent, headerKey: string): KioskLayout {
  const viewport = useViewport();
  const scale = kioskScale(viewport.width_px, viewport.height_px);
  const [fit, setFit] = useState(1);
  // A new window or header: from the full scale again (React's "state from a change" pattern).
  const resetKey = `${viewport.width_px}x${viewport.height_px}|${headerKey}`;
  const [seen, setSeen] = useState(resetKey);
  if (seen !== resetKey) {
    setSeen(resetKey);
    setFit(1);
  }
  const u = scale.u * fit;
  const box = useBoxOf(body);
  const layout = useMemo(() => (box === null ? null : bodyLayout(box, content, { u, landscape: scale.landscape })), [box, content, u, scale.landscape]);
  const fits = layout?.fits ?? true;
  useEffect(() => {
    if (fits || fit <= MIN_FIT) return;
    // A smaller scale shrinks the header and gives the body more room, which the observer
    // reports a moment later: judged on the room measured before, every step would look too
    // small and the scale would fall to its least. Only the room as it is now may step down.
    const el = body.current;
    if (el !== null && box !== null && (el.clientWidth !== box.width_px || el.clientHeight !== box.height_px)) return;
    setFit((f) => Math.max(MIN_FIT, f * FIT_STEP));
  }, [fits, fit, body, box]);
  return { u, landscape: scale.landscape, body: layout };
}

/**
 * The plotting area's height (px) for a plot in `slot` that may be `slotHeight_px` high: the
 * slot less the plot's title and legend, measured in the page at the scale `u`.
 */
export function usePlotHeight(slot: RefObject<HTMLElement | null>, slotHeight_px: number, u: number): number | undefined {
  const [chrome_px, setChrome] = useState<number | null>(null);
  useLayoutEffect(() => {
    const figure = slot.current?.querySelector("figure");
    const area = slot.current?.querySelector(".plot__area");
    if (figure == null || area == null) return;
    const measured = Math.ceil(figure.getBoundingClientRect().height - area.getBoundingClientRect().height);
    setChrome((prev) => (prev !== null && Math.abs(prev - measured) <= 1 ? prev : measured));
  }, [slot, slotHeight_px, u]);
  if (slotHeight_px <= 0) return undefined;
  // Until measured, a guess of a title and a legend line at this scale.
  return Math.max(40, Math.floor(slotHeight_px - (chrome_px ?? 90 * u)));
}
