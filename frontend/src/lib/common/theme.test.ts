import { describe, expect, it } from "vitest";
import { ThemeStore, initialChoice, parseChoice, resolveTheme, type ThemeEnvironment } from "./theme";

/** A browser stand-in: a storage slot and a system preference that can change. */
function environment(options: { search?: string; stored?: string | null; dark?: boolean } = {}) {
  let stored = options.stored ?? null;
  let dark = options.dark ?? false;
  const listeners = new Set<() => void>();
  const env: ThemeEnvironment = {
    search: options.search ?? "",
    read: () => stored,
    write: (value) => {
      stored = value;
    },
    systemDark: () => dark,
    onSystemChange: (listener) => {
      listeners.add(listener);
      return () => listeners.delete(listener);
    },
  };
  return {
    env,
    stored: () => stored,
    setSystemDark(next: boolean) {
      dark = next;
      for (const l of listeners) l();
    },
    listenerCount: () => listeners.size,
  };
}

describe("theme choice", () => {
  it("resolves system to the system's preference and keeps an explicit choice", () => {
    expect(resolveTheme("system", true)).toBe("dark");
    expect(resolveTheme("system", false)).toBe("light");
    expect(resolveTheme("light", true)).toBe("light");
    expect(resolveTheme("dark", false)).toBe("dark");
  });

  it("starts from the URL, else the remembered choice, else the system", () => {
    expect(initialChoice("?robot=a&theme=dark", "light")).toBe("dark");
    expect(initialChoice("?robot=a", "light")).toBe("light");
    expect(initialChoice("", null)).toBe("system");
    expect(initialChoice("?theme=purple", "nonsense")).toBe("system");
    expect(parseChoice("dark")).toBe("dark");
    expect(parseChoice(null)).toBeNull();
  });

  it("follows the system while the choice is system", () => {
    const browser = environment({ dark: false });
    const store = new ThemeStore(browser.env);
    store.start();
    const seen: string[] = [];
    store.subscribe(() => seen.push(store.getSnapshot().theme));
    expect(store.getSnapshot()).toEqual({ choice: "system", theme: "light" });
    browser.setSystemDark(true);
    expect(store.getSnapshot().theme).toBe("dark");
    expect(seen).toEqual(["dark"]);
    store.stop();
    expect(browser.listenerCount()).toBe(0);
  });

  it("remembers a person's choice, which then ignores the system", () => {
    const browser = environment({ dark: true });
    const store = new ThemeStore(browser.env);
    store.start();
    store.choose("light");
    expect(browser.stored()).toBe("light");
    expect(store.getSnapshot()).toEqual({ choice: "light", theme: "light" });
    browser.setSystemDark(false);
    browser.setSystemDark(true);
    expect(store.getSnapshot().theme).toBe("light");
    // A new page in the same browser starts with it.
    expect(new ThemeStore(environment({ stored: browser.stored(), dark: true }).env).getSnapshot().theme).toBe("light");
  });
});
