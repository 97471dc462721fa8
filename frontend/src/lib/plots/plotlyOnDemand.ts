/**
 * Layer: Plotly asked for when a plot first needs it (plain TypeScript). A live plot nobody
 * points at is its canvas picture and needs no Plotly; lib/plots/plotlyAdapter.ts loads Plotly's
 * chunk the first time one is asked for (docs/architecture.md "Plots").
 */
import type { PlotBackend } from "./plotBackend";

export class PlotlyOnDemand {
  /** Asked for and not come yet: not asked again (but again after a failure). */
  private asked = false;

  constructor(
    private readonly backend: PlotBackend,
    /** Told once Plotly has come after this asked for it. */
    private readonly came: () => void,
  ) {}

  /** Whether Plotly can draw now; if not, it is asked for (the caller draws when told). */
  ready(): boolean {
    if (this.backend.ready?.() ?? true) return true;
    if (!this.asked && this.backend.load !== undefined) {
      this.asked = true;
      this.backend.load().then(
        () => {
          this.asked = false;
          this.came();
        },
        (error: unknown) => {
          this.asked = false;
          console.warn("Plotly could not be loaded; asked again at the next need", error);
        },
      );
    }
    return false;
  }
}
