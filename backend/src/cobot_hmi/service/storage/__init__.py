"""Layer: service. The service's database: its schema and migrations, audit, events, tag names."""
