/**
 * Layer: the page's theme in the browser (DOM glue for `lib/common/theme`): one store per page, its
 * theme written to `<html data-theme>` and `color-scheme` (the stylesheets key on them), a hook
 * for views that draw themselves (plots, 3D view), and the switch shown on the panel.
 */
import { useSyncExternalStore } from "react";
import { THEME_CHOICES, THEME_STORAGE_KEY, ThemeStore, parseChoice, type Theme, type ThemeEnvironment } from "../lib/common/theme";

function browserEnvironment(): ThemeEnvironment {
  const query = typeof window.matchMedia === "function" ? window.matchMedia("(prefers-color-scheme: dark)") : null;
  return {
    search: window.location.search,
    read: () => {
      try {
        return window.localStorage.getItem(THEME_STORAGE_KEY);
      } catch {
        return null;
      }
    },
    write: (value) => {
      try {
        window.localStorage.setItem(THEME_STORAGE_KEY, value);
      } catch {
        // storage unavailable: the choice lasts for this page only
      }
    },
    systemDark: () => query?.matches ?? false,
    onSystemChange: (listener) => {
      query?.addEventListener("change", listener);
      return () => query?.removeEventListener("change", listener);
    },
  };
}

let store: ThemeStore | null = null;

function apply(theme: Theme): void {
  const root = document.documentElement;
  root.dataset.theme = theme;
  root.style.colorScheme = theme;
}

/** The page's theme store, created and applied to the document on first use. */
export function themeStore(): ThemeStore {
  if (store === null) {
    const created = new ThemeStore(browserEnvironment());
    created.subscribe(() => apply(created.getSnapshot().theme));
    created.start();
    apply(created.getSnapshot().theme);
    store = created;
  }
  return store;
}

/** The theme shown now (re-renders when it changes). */
export function useTheme(): Theme {
  const s = themeStore();
  return useSyncExternalStore(s.subscribe, s.getSnapshot).theme;
}

/** The panel's theme switch: System, Light or Dark, remembered in this browser. */
export function ThemeSwitch() {
  const s = themeStore();
  const { choice } = useSyncExternalStore(s.subscribe, s.getSnapshot);
  return (
    <label className="theme-switch">
      <span>Theme</span>
      <select
        data-testid="theme-switch"
        value={choice}
        onChange={(e) => {
          const next = parseChoice(e.target.value);
          if (next !== null) s.choose(next);
        }}
      >
        {THEME_CHOICES.map(([value, words]) => (
          <option key={value} value={value}>
            {words}
          </option>
        ))}
      </select>
    </label>
  );
}
