"""Layer: emulator (I/O). Imports the layout, the codec and ``cobot_hmi.enip``; never the
scanner or the service.

The robot's side of EtherNet/IP: :class:`~cobot_hmi.emulator.target.Target` is a class 1
target (adapter) on TCP 44818 and UDP 2222 in front of a
:class:`~cobot_hmi.emulator.process_image.ProcessImage`, the robot behind it.
"""
