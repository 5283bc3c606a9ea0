"""The sensor hub's client over ros4mat: :class:`Hub` (the client), its link (:mod:`.link`),
the SUBSCRIBE settings (:mod:`.subscription`), the hub's clock (:mod:`.clock`), the reply
decoder (:mod:`.decode`) and the command-line helpers built on it (:mod:`.tools`)."""

from robocli.devices.hub.client import Hub, Reading

__all__ = ["Hub", "Reading"]
