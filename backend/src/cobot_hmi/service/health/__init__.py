"""Layer: service. Robot health in the running service (issue 40, docs/health.md "In the
service"): the pure engine (``cobot_hmi.health``) fed every robot's frames and measured cycles
off the cyclic path, its state and baselines in the database, its verdicts as advisory alarms
and ``health`` events."""
