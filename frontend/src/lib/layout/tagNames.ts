/**
 * Layer: reading a robot's tag names with a plain GET (no React). For the kiosk, which may not
 * import the REST client of `lib/api/api.ts` (its import graph is checked to reach no write): this
 * module can only read. The panel gets its names from its tag-names view (lib/alarms/alarmsApi.ts).
 */
import type { TagNames } from "./tags";

/** `{key: name}` of the named points of `robot`, or null when the service did not answer them. */
export async function fetchTagNames(robot: string, token: string | null): Promise<TagNames | null> {
  const headers: Record<string, string> = { Accept: "application/json" };
  if (token !== null && token !== "") headers.Authorization = `Bearer ${token}`;
  const response = await fetch(`/api/v1/robots/${encodeURIComponent(robot)}/tags`, { method: "GET", headers, credentials: "same-origin" });
  if (!response.ok) return null;
  const body = (await response.json()) as { tags?: unknown };
  const tags = body.tags;
  if (typeof tags !== "object" || tags === null || Array.isArray(tags)) return null;
  const names: Record<string, string> = {};
  for (const [key, name] of Object.entries(tags as Record<string, unknown>)) if (typeof name === "string" && name !== "") names[key] = name;
  return names;
}
