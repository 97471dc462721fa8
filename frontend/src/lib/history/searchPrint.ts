/**
 * Layer: printing one section of the panel (styles/print.css: with `data-print-section` on the
 * body only that section goes on paper, every control left off). No React.
 */

/** The browser's print of the panel's section `id` alone. */
export function printSection(id: string): void {
  document.body.dataset.printSection = id;
  try {
    window.print();
  } finally {
    delete document.body.dataset.printSection;
  }
}
