/**
 * Layer: reading a robot's model with a plain GET (no React), for the kiosk's 3D view: the kiosk
 * may not import the REST client of `lib/api/api.ts` (its import graph is checked to reach no
 * write), and this module can only read. The panel has the model from its robot list.
 */

/** The model `GET /api/v1/robots/{name}` reports (its identity's product name), or null. */
export async function fetchRobotModel(robot: string, token: string | null): Promise<string | null> {
  const headers: Record<string, string> = { Accept: "application/json" };
  if (token !== null && token !== "") headers.Authorization = `Bearer ${token}`;
  const response = await fetch(`/api/v1/robots/${encodeURIComponent(robot)}`, { method: "GET", headers, credentials: "same-origin" });
  if (!response.ok) return null;
  const body = (await response.json()) as { model?: unknown };
  return typeof body.model === "string" && body.model !== "" ? body.model : null;
}
