/**
 * axe-core's serious and critical findings on a page (or inside `include`, a CSS selector).
 *
 * Legacy mode: axe runs in the page as one `axe.run`, instead of a partial run per frame whose
 * results (every node checked, thousands on a panel of live plots) travel to the test and into a
 * blank page of their own to be put together. The panel has no frames, so the rules and the
 * nodes checked are the same; it takes half the time.
 *
 * Violations only (axe's `resultTypes`): every violating node is still reported, but the rules
 * that pass list one node each instead of every node they checked. On the panel (4,300 elements)
 * an audit took 4.3 CPU-s instead of 10, the same violations found.
 */
import AxeBuilder from "@axe-core/playwright";
import type { Page } from "@playwright/test";

export async function seriousViolations(page: Page, include?: string): Promise<string[]> {
  const builder = new AxeBuilder({ page }).setLegacyMode(true).options({ resultTypes: ["violations"] });
  if (include !== undefined) builder.include(include);
  const results = await builder.analyze();
  return results.violations
    .filter((v) => v.impact === "serious" || v.impact === "critical")
    .map((v) => `${v.id} (${v.impact}): ${v.nodes.map((n) => n.target.join(" ")).slice(0, 5).join(", ")}`);
}

/**
 * The violations of the axe rules named (any impact; experimental ones such as
 * label-content-name-mismatch run too, being named), in the page or inside `include`.
 */
export async function ruleViolations(page: Page, rules: string[], include?: string): Promise<string[]> {
  const builder = new AxeBuilder({ page }).setLegacyMode(true).withRules(rules).options({ resultTypes: ["violations"] });
  if (include !== undefined) builder.include(include);
  const results = await builder.analyze();
  return results.violations.map((v) => `${v.id} (${v.impact}): ${v.nodes.length} nodes, ${v.nodes.map((n) => n.target.join(" ")).slice(0, 3).join(", ")}`);
}
