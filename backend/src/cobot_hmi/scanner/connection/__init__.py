"""Layer: scanner. The parts of one class 1 connection held by
:class:`~cobot_hmi.scanner.originator.Originator`, a module per concern: ``state`` (its state,
errors and figures as others see them), ``settings``, ``core`` (the state the parts share),
``o2t_send`` (the O→T send path), ``t2o_receive`` (the T→O receive path and the watchdog),
``lifecycle`` (Forward Open and Close, supervision with backoff, teardown).
"""
