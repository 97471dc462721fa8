/**
 * Layer: the kiosk's "maintenance due" mark (no React, no DOM but `fetch`): read with a plain GET
 * of the robot's health (the kiosk has no REST client and writes nothing), its words from the
 * verdict, so a person in the cell sees from a distance that the robot asks for a look.
 */
import type { HealthAnswer, Verdict } from "./healthTypes";
import { isVerdict, worstVerdict } from "./verdicts";

/** The health verdicts are judged again every few seconds in the service; a kiosk needs less. */
export const MAINTENANCE_REFRESH_MS = 10_000;

export interface MaintenanceMark {
  readonly due: boolean;
  readonly verdict: Verdict | null;
  /** The mark's words: "MAINTENANCE DUE: J3" (null: no mark). */
  readonly words: string | null;
}

export const NO_MARK: MaintenanceMark = { due: false, verdict: null, words: null };

/** The mark of a health answer: shown while the service says maintenance is due. */
export function maintenanceMark(answer: Pick<HealthAnswer, "maintenance_due" | "verdict" | "joints"> | null): MaintenanceMark {
  if (answer === null) return NO_MARK;
  const verdict = isVerdict(answer.verdict) ? answer.verdict : worstVerdict(answer.joints);
  const due = answer.maintenance_due ?? verdict === "act";
  if (!due) return { due: false, verdict, words: null };
  const named = answer.joints.filter((j) => j.verdict !== "ok").map((j) => `J${j.joint}`);
  return { due: true, verdict, words: named.length > 0 ? `MAINTENANCE DUE: ${named.join(", ")}` : "MAINTENANCE DUE" };
}

/** The robot's health as the kiosk may read it (null: no answer, or none it may read). */
export async function fetchHealth(robot: string, token: string | null): Promise<HealthAnswer | null> {
  const headers: Record<string, string> = { Accept: "application/json" };
  if (token !== null && token !== "") headers.Authorization = `Bearer ${token}`;
  const response = await fetch(`/api/v1/robots/${encodeURIComponent(robot)}/health`, { method: "GET", headers, credentials: "same-origin" });
  if (!response.ok) return null;
  const body = (await response.json()) as HealthAnswer;
  return Array.isArray(body.joints) ? body : null;
}
