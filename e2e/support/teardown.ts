/**
 * After the run (Playwright's global teardown, once every worker has stopped its cell): the
 * run's state directory goes, every cell's recording and database in it, unless E2E_KEEP_STATE
 * asks to keep it for a look or it is the caller's own (E2E_STATE_DIR).
 */
import { rmSync } from "node:fs";
import { settings } from "./settings";

export default function teardown(): void {
  if (process.env.E2E_STATE_DIR_MADE !== "1") return; // the caller's own directory
  if (process.env.E2E_KEEP_STATE === undefined || process.env.E2E_KEEP_STATE === "") {
    rmSync(settings.stateDir, { recursive: true, force: true });
  } else {
    console.log(`e2e state kept in ${settings.stateDir}`);
  }
}
