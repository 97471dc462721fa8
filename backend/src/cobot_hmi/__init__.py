"""cobot-hmi: a web HMI for a Doosan collaborative robot over EtherNet/IP class 1 I/O."""

__version__ = "0.1.0"
