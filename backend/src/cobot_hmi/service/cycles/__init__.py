"""Layer: service. Cycle timing: each robot's cycles measured from its frames (a trigger edge to
the next), kept in the database, answered with their statistics (docs/operations.md "Cycle
timing")."""
