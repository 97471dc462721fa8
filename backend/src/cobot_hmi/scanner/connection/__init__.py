"""Layer: scanner. The parts of one class 1 connection that
:class:`~cobot_hmi.scanner.originator.Originator` composes, an object with one job per module,
each given only what it needs: ``state`` (the state, errors and figures as others see them, and
``ConnectionStatus``, the state's record), ``originator_settings``, ``link`` (one Forward
Open's numbers, handed from the lifecycle to the other two), ``o2t_send`` (``O2TSender``: what
O→T carries), ``t2o_receive`` (``T2OReceiver``: T→O in, the figures, the watchdog),
``lifecycle`` (``ConnectionLifecycle``: the port, Forward Open and Close, supervision with
backoff, teardown).
"""
