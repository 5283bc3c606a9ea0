"""Links of the serving layer: one client's byte stream (TCP or pty) and its thread.

A :class:`Link` frames what it receives with the C framer (bounded by ``max_frame``), hands
each complete frame to its session and writes the replies inline from its own thread. A
partial frame with no new byte for ``byte_timeout`` is abandoned: its first byte is dropped and
the rest rescanned (with ``strict`` framing the link is closed instead). :meth:`Link.send`
never blocks: output the peer cannot take now waits in a bounded queue, and a peer that leaves
it unread for ``send_timeout`` is dropped. Nothing is copied to wait: a reply is written
straight from the caller's buffers and the queue keeps views of what the peer has not taken
yet (a large reply, a camera frame, is not copied). Pushes from another thread (a ticker) are
flushed by the next push or by the link's own thread.

With ``pace`` (request/reply protocols) a link reads and handles no request while one of its
replies waits for the peer: a client that asks without reading holds at most one reply in the
server, and its next requests wait in the kernel's buffers. An :class:`OutputBudget` bounds the
memory the output waiting over every link of a server holds: the links that cause it pay for
it (dropped, those waiting longest first; a :attr:`Link.privileged` one never for another).

Used through :class:`robocli.serving.server.Server`; nothing here is global.

The package holds :mod:`~robocli.serving.links.limits` (what every link of a server obeys and
counts: :class:`LinkLimits`, :class:`OutputBudget`, :class:`ServerLinkStats`),
:mod:`~robocli.serving.links.base` (the :class:`ServerSession` and :class:`UnframedHook`
protocols and :class:`Link`: framing, dispatch and the output queue every link shares),
:mod:`~robocli.serving.links.tcp` (:class:`TcpLink`) and :mod:`~robocli.serving.links.pty`
(:class:`PtyLink`). Import from here.
"""

from __future__ import annotations

from robocli.serving.links.base import Link, ServerSession, UnframedHook
from robocli.serving.links.limits import LinkLimits, OutputBudget, ServerLinkStats
from robocli.serving.links.pty import PtyLink
from robocli.serving.links.tcp import DONTWAIT, TcpLink

__all__ = [
    "DONTWAIT",
    "Link",
    "LinkLimits",
    "OutputBudget",
    "PtyLink",
    "ServerLinkStats",
    "ServerSession",
    "TcpLink",
    "UnframedHook",
]
