"""A Hokuyo laser's channels: its streamed scans -> ``foxglove.LaserScan`` (see
:mod:`.sources` for the topics); its SCIP lines both ways go to the raw channels (protocol
``scip2``: requests on ``tx``, reply and data blocks on ``rx``)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from robocli.errors import InvalidArgument
from robocli.io import schemas as S
from robocli.io.record.links import RawLink, Sink, json_text, new_link, record_scans

if TYPE_CHECKING:
    from robocli.devices.laser import Laser, Scan
    from robocli.robots.geometry import Mount

__all__ = ["LaserDecoder", "attach_laser"]


def attach_laser(rec: Sink, laser: Laser, name: str | None, *, parent: str | None = None,
                 mount: Mount | None = None) -> str:  # fmt: skip
    """``name``: the default ``laser`` (numbered), or the name of a link made with
    :meth:`Recorder.listener` (protocol ``scip2``) and given to ``Laser.connect(listeners=)``,
    so that the handshake is recorded too. The scans recorded are the streamed ones
    (``laser.start()``, :meth:`Laser.scans`). ``parent``: the frame the laser is mounted on
    (a Pioneer's ``pioneer/base_link``), placed there at ``mount`` by a ``/NAME/tf``
    FrameTransform written with every scan."""
    link: RawLink | None = rec.links.get(name) if name is not None else None
    if link is not None and link.decoder is not None:
        raise InvalidArgument(f"{name!r} is recorded already")
    if link is None:  # not listening since the handshake: from now on
        name = rec.unique_name(name or "laser")
        link = new_link(rec, name, "scip2", url=laser.url)
        laser.session.listeners.add(link)
        rec.on_close(lambda: laser.session.listeners.remove(link))
    assert name is not None
    decoder = LaserDecoder(rec, name, laser.epoch(0.0), parent, mount)
    link.decoder = decoder.ignore  # the scans come decoded from the client: no second decode
    record_scans(rec, laser, "scans", decoder.scan)
    return name


class LaserDecoder:
    """Scans (writer thread) -> ``/NAME/scan`` (foxglove.LaserScan in frame ``NAME/laser``,
    ranges in m, 0 where the sensor sent an error code, intensities when measured). Log time:
    when the scan arrived; publish time: the sensor's timestamp mapped to the host clock
    (:attr:`Scan.t`)."""

    def __init__(self, rec: Sink, name: str, epoch: float, parent: str | None = None,
                 mount: Mount | None = None) -> None:  # fmt: skip
        self.rec, self.frame, self.topic = rec, f"{name}/laser", f"/{name}/scan"
        self._epoch = epoch  # the laser's host epoch seconds at monotonic 0
        self._cid: int | None = None
        self._tf: tuple[str, str, tuple[float, float, float], dict[str, float]] | None = None
        if parent is not None:
            m = mount if mount is not None else _centre()
            self._tf = (f"/{name}/tf", parent, (m.x, m.y, 0.0), _rotation(m))
        self._tf_cid: int | None = None
        self.scans = 0

    def ignore(self, direction: str, payload: bytes, ns: int) -> None:
        """Raw frames: already in the raw channels, nothing more to decode."""

    def scan(self, scan: Scan) -> None:
        angles = scan.angles
        if not len(angles):
            return
        ns = self.rec.log_ns(scan.received - self._epoch)
        publish = int(scan.t * 1e9)
        inten = None if scan.intensities is None else [float(v) for v in scan.intensities]
        data = S.laser_scan(publish, self.frame, float(angles[0]), float(angles[-1]),
                            scan.ranges.tolist(), inten)  # fmt: skip
        if self._cid is None:
            self._cid = self.rec.channel(self.topic, "foxglove.LaserScan")
        self.rec.write(self._cid, json_text(data).encode(), ns, publish)
        self.scans += 1
        if self._tf is not None:
            topic, parent, xyz, rot = self._tf
            if self._tf_cid is None:
                self._tf_cid = self.rec.channel(topic, "foxglove.FrameTransform")
            tf = S.frame_transform(publish, parent, self.frame, xyz, rot)
            self.rec.write(self._tf_cid, json_text(tf).encode(), ns, publish)


def _centre() -> Mount:
    from robocli.robots.geometry import Mount

    return Mount()


def _rotation(m: Mount) -> dict[str, Any]:
    """The quaternion of yaw ``m.th``, then upside down (roll pi) when ``m.flipped``."""
    c, s = math.cos(m.th / 2), math.sin(m.th / 2)
    if m.flipped:
        return {"x": c, "y": s, "z": 0.0, "w": 0.0}
    return {"x": 0.0, "y": 0.0, "z": s, "w": c}
