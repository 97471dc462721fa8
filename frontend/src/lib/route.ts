/** Layer: pure routing rule: which face a path shows (no React, no DOM). */
export function isKioskPath(pathname: string): boolean {
  return /^\/kiosk\/?$/.test(pathname);
}
