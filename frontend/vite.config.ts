// Vite builds the panel (/) and the kiosk (/kiosk) into frontend/dist, which the backend serves
// with an SPA fallback. In development, /api (REST and the WebSocket) goes to a local backend.
import { defineConfig } from "vitest/config";
import react from "@vitejs/plugin-react";

const backend = process.env.COBOT_HMI_BACKEND ?? "http://127.0.0.1:8000";

export default defineConfig({
  plugins: [react()],
  build: {
    outDir: "dist",
    emptyOutDir: true,
    // Plotly's partial bundle is one large chunk by design; it is loaded once and cached.
    chunkSizeWarningLimit: 1600,
  },
  server: {
    proxy: {
      "/api": { target: backend, ws: true, changeOrigin: false },
      "/healthz": backend,
      "/readyz": backend,
    },
  },
  test: {
    environment: "node",
    include: ["src/**/*.test.ts"],
  },
});
