/**
 * Entry: `/kiosk` loads the kiosk, anything else the commissioning panel. Each face is its own
 * chunk, loaded on demand, so the kiosk's bundle does not even contain the panel's write code.
 */
import { StrictMode, type ComponentType } from "react";
import { createRoot } from "react-dom/client";
import { isKioskPath } from "./lib/route";
import "./styles/common.css";

async function load(): Promise<ComponentType> {
  if (isKioskPath(window.location.pathname)) return (await import("./kiosk/KioskApp")).KioskApp;
  return (await import("./panel/PanelApp")).PanelApp;
}

const rootElement = document.getElementById("root");
if (rootElement !== null) {
  const root = createRoot(rootElement);
  void load().then((App) => {
    root.render(
      <StrictMode>
        <App />
      </StrictMode>,
    );
  });
}
