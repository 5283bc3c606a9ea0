"""What every server of robocli stands on: the built-in simulators and the hub server.

:mod:`robocli.serving.server` (:class:`~robocli.serving.server.Server`: listeners, limits,
refusals, a bounded close), :mod:`robocli.serving.links` (one client's byte stream, TCP or
pty, and its thread) and :mod:`robocli.serving.ticker` (the periodic clock of physics, state
streams and sensor sources). Import from those modules: this package imports nothing, so
that a light user of one part does not load the others.
"""
