/**
 * Entry: `/kiosk` loads the kiosk, `/fleet` the fleet overview, `/health` a robot's health page,
 * anything else the commissioning panel. Each face is its own chunk, loaded on demand, so the kiosk's bundle does not even
 * contain the panel's write code.
 */
import { StrictMode, type ComponentType } from "react";
import { createRoot } from "react-dom/client";
import { themeStore } from "./components/theme";
import { faceOf } from "./lib/common/route";
import "./styles/common.css";
import "./styles/theme.css";
import "./styles/responsive.css";

// The face and the theme on <html> before the first render: no flash of the other theme.
document.documentElement.dataset.face = faceOf(window.location.pathname);
themeStore();

async function load(): Promise<ComponentType> {
  switch (faceOf(window.location.pathname)) {
    case "kiosk":
      return (await import("./kiosk/KioskApp")).KioskApp;
    case "fleet":
      return (await import("./fleet/FleetApp")).FleetApp;
    case "health":
      return (await import("./health/HealthApp")).HealthApp;
    case "plant":
      return (await import("./plant/PlantApp")).PlantApp;
    case "panel":
      return (await import("./panel/PanelApp")).PanelApp;
  }
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
