/**
 * Layer: the light/dark theme choice (plain TypeScript; the browser's storage and colour-scheme
 * query are passed in, so this runs in tests without a DOM).
 *
 * A person chooses "system" (follow the operating system's setting, the default), "light" or
 * "dark"; the panel remembers the choice in local storage, a kiosk may name it in its URL
 * (`/kiosk?theme=dark`), which wins for that page. Must not import React or any component.
 */
export type Theme = "light" | "dark";
export type ThemeChoice = "system" | Theme;

export const THEME_STORAGE_KEY = "cobot-hmi.theme";

/** The choices in the order a switch offers them, with their words. */
export const THEME_CHOICES: readonly (readonly [ThemeChoice, string])[] = [
  ["system", "System"],
  ["light", "Light"],
  ["dark", "Dark"],
];

export function parseChoice(value: string | null | undefined): ThemeChoice | null {
  return value === "system" || value === "light" || value === "dark" ? value : null;
}

/** The theme shown for a choice, given whether the system prefers dark. */
export function resolveTheme(choice: ThemeChoice, systemDark: boolean): Theme {
  if (choice === "system") return systemDark ? "dark" : "light";
  return choice;
}

/** The choice a page starts with: its URL's `theme=`, else the remembered one, else the system. */
export function initialChoice(search: string, stored: string | null): ThemeChoice {
  return parseChoice(new URLSearchParams(search).get("theme")) ?? parseChoice(stored) ?? "system";
}

/** What the store needs from the browser (window.localStorage and matchMedia, or test doubles). */
export interface ThemeEnvironment {
  readonly search: string;
  read(): string | null;
  write(value: string): void;
  /** Whether the system prefers dark now. */
  systemDark(): boolean;
  /** Call `listener` when the system's preference changes; returns the unsubscribe. */
  onSystemChange(listener: () => void): () => void;
}

export interface ThemeState {
  readonly choice: ThemeChoice;
  readonly theme: Theme;
}

type Listener = () => void;

/** The page's theme: the choice, the resolved theme, and who to tell when either changes. */
export class ThemeStore {
  private state: ThemeState;
  private readonly listeners = new Set<Listener>();
  private unwatch: (() => void) | null = null;

  constructor(private readonly env: ThemeEnvironment) {
    const choice = initialChoice(env.search, env.read());
    this.state = { choice, theme: resolveTheme(choice, env.systemDark()) };
  }

  /** Follow the system's setting from now on (while the choice is "system"). */
  start(): void {
    if (this.unwatch !== null) return;
    this.unwatch = this.env.onSystemChange(() => this.update(this.state.choice));
  }

  stop(): void {
    this.unwatch?.();
    this.unwatch = null;
  }

  subscribe = (listener: Listener): (() => void) => {
    this.listeners.add(listener);
    return () => {
      this.listeners.delete(listener);
    };
  };

  getSnapshot = (): ThemeState => this.state;

  /** A person's choice: shown at once and remembered. */
  choose(choice: ThemeChoice): void {
    this.env.write(choice);
    this.update(choice);
  }

  private update(choice: ThemeChoice): void {
    const theme = resolveTheme(choice, this.env.systemDark());
    if (theme === this.state.theme && choice === this.state.choice) return;
    this.state = { choice, theme };
    for (const listener of this.listeners) listener();
  }
}
