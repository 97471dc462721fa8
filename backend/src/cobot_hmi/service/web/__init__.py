"""Layer: service. The web service's settings (HTTP, sessions, WebSocket streams, TLS): below
the robots and the API that read them, so the settings composed of every concern's
(``service.service_settings``) never import the API."""
