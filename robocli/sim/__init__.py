"""Built-in simulators: real servers speaking the same bytes as the hardware.

``robocli.sim.pioneer.server`` is an ARCOS robot (Pioneer P3-DX, P3-AT, AmigoBot, ...) on TCP and on
a pseudo-terminal; ``robocli.sim.world`` holds the 2-D worlds it drives in. They double as the
fixtures of the test suite.
"""
