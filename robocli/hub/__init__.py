"""The sensor hub: sources -> one ring per sensor -> front-ends (ros4mat v3 over TCP).

::

    from robocli.hub import HubServer
    with HubServer(port=0, sim=True) as srv:   # started; srv.url is tcp://127.0.0.1:PORT
        ...

See :mod:`robocli.hub.registry` (sensors and clients), :mod:`robocli.hub.rings` (one ring
per sensor, a cursor per client), :mod:`robocli.hub.sources` and
:mod:`robocli.hub.frontends.ros4mat` (the ros4mat front-end).
"""

from __future__ import annotations

from robocli.hub.server import HubServer, tune_hub_process

__all__ = ["HubServer", "tune_hub_process"]
