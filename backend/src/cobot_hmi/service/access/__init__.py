"""Layer: service. Who may do what: users, sessions, API tokens, the login throttle."""
