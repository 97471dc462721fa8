"""Layer: service. What the kiosk is told by the service (``kiosk_settings``)."""
