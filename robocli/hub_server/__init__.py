"""The sensor hub: sources -> one ring per sensor -> front-ends (ros4mat v3 over TCP).

::

    from robocli.hub_server import HubServer
    with HubServer(port=0, sim=True) as srv:   # started; srv.url is tcp://127.0.0.1:PORT
        ...

See :mod:`robocli.hub_server.registry` (sensors and clients),
:mod:`robocli.hub_server.rings` (one ring per sensor, a cursor per client),
:mod:`robocli.hub_server.sources` and :mod:`robocli.hub_server.frontends.ros4mat` (the ros4mat
front-end).
"""

from __future__ import annotations

from robocli.hub_server.server import HubServer, tune_hub_process

__all__ = ["HubServer", "tune_hub_process"]
