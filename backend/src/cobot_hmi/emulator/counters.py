"""Layer: emulator. Imports nothing of the project.

What the target counts: every bad packet is counted here, never raised (common rules: "bad
input never crashes a process: clear error, counted, last good state kept").
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class TargetCounters:
    tcp_sessions: int = 0
    encapsulation_malformed: int = 0
    encapsulation_unsupported: int = 0
    encapsulation_bad_session: int = 0
    explicit_requests: int = 0
    forward_opens: int = 0
    forward_open_refusals: int = 0
    forward_closes: int = 0
    watchdog_timeouts: int = 0
    udp_malformed: int = 0
    udp_unknown_connection: int = 0
    udp_stale: int = 0
    udp_duplicates: int = 0
    t2o_sent: int = 0
    t2o_dropped: int = 0
    t2o_corrupted: int = 0
    internal_errors: int = 0
    tcp_connections_open: int = 0
    """A gauge: TCP connections on the encapsulation port now (bounded by max_tcp_sessions)."""
    tcp_connections_peak: int = 0
    tcp_sessions_refused: int = 0
    tcp_sessions_timed_out: int = 0
    tcp_sessions_inactive: int = 0
    udp_list_identity: int = 0
    udp_list_services: int = 0
    udp_discovery_ignored: int = 0
