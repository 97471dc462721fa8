/**
 * The panel on a phone (issue 38): its plots stay folded until asked for (a button in their
 * place), and its stream carries only the fields of the sections in view, at the rate a phone
 * draws (lib/stream/phoneStream.ts). Wide screens are untouched: every plot drawn, every frame streamed.
 */
import { useEffect, useState, useSyncExternalStore, type CSSProperties, type ReactNode } from "react";
import { PHONE_MAX_WIDTH_PX, panelSubscription } from "../lib/stream/phoneStream";
import { JOINT_COLUMNS, headerWithUnit } from "../lib/layout/readouts";
import type { LiveRuntime } from "../lib/stream/runtime";

const NARROW_QUERY = `(max-width: ${PHONE_MAX_WIDTH_PX}px)`;

function subscribeNarrow(onChange: () => void): () => void {
  const query = window.matchMedia(NARROW_QUERY);
  query.addEventListener("change", onChange);
  return () => query.removeEventListener("change", onChange);
}

/** Whether the window is a phone's (as wide as lib/stream/phoneStream.ts's `PHONE_MAX_WIDTH_PX` or less). */
export function useNarrow(): boolean {
  return useSyncExternalStore(subscribeNarrow, () => window.matchMedia(NARROW_QUERY).matches);
}

/** A section's plots: on a phone folded behind a button until opened (then for every section). */
export function FoldedPlots({ narrow, open, onOpen, label, children }: { narrow: boolean; open: boolean; onOpen: () => void; label: string; children: ReactNode }) {
  if (!narrow || open) return <>{children}</>;
  return (
    <button type="button" className="phone-plots__open" data-testid="phone-plots-open" onClick={onOpen}>
      {label}
    </button>
  );
}

/** The sections of `.panel-main` on screen (or within a screen's height of it), by id. */
function useSectionsInView(active: boolean): ReadonlySet<string> {
  const [inView, setInView] = useState<ReadonlySet<string>>(() => new Set());
  useEffect(() => {
    if (!active || typeof IntersectionObserver === "undefined") return;
    const shown = new Set<string>();
    const observer = new IntersectionObserver(
      (entries) => {
        for (const entry of entries) {
          if (entry.isIntersecting) shown.add(entry.target.id);
          else shown.delete(entry.target.id);
        }
        setInView(new Set(shown));
      },
      // A screen ahead: a section's numbers have come by the time it is scrolled to.
      { rootMargin: "100% 0px 100% 0px" },
    );
    for (const section of Array.from(document.querySelectorAll<HTMLElement>(".panel-main > section[id]"))) observer.observe(section);
    return () => observer.disconnect();
  }, [active]);
  return inView;
}

/** Asks `runtime`'s stream for what the page shows (renders nothing). */
export function PhoneStream({ runtime, narrow, plotsOpen }: { runtime: LiveRuntime; narrow: boolean; plotsOpen: boolean }) {
  const inView = useSectionsInView(narrow);
  useEffect(() => {
    runtime.stream.subscribe(panelSubscription(narrow, inView, plotsOpen));
  }, [runtime, narrow, inView, plotsOpen]);
  return null;
}

/**
 * The joint table's titles as CSS strings (`--label-joint_position: "Position [degree]"`): a
 * phone's stacked table writes each above its figure (styles/phone.css).
 */
export const JOINT_LABEL_VARS = Object.fromEntries(JOINT_COLUMNS.map((c) => [`--label-${c.field}`, JSON.stringify(headerWithUnit(c))])) as CSSProperties;
