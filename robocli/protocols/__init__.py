"""Wire protocols, each message declared once with :mod:`construct`.

One module per protocol (``arcos``, ``simple_message``, ``ros4mat``, ``scip2``). Modules here
know bytes and field meanings, never sockets, devices or the terminal. Golden byte vectors for every
protocol live in ``specs/*.json`` at the repository root and are checked by the C and the
Python test suites alike.
"""
