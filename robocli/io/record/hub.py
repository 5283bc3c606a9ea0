"""The hub's channels: one message per sample at its acquisition time (see :mod:`.sources`
for the topics), and the pull loop that feeds them."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

import numpy as np

from robocli.errors import InvalidArgument
from robocli.io import schemas as S
from robocli.io.record.links import RawLink, Sink, json_text

if TYPE_CHECKING:
    from robocli.devices.hub.client import Hub

__all__ = ["HubDecoder", "attach_hub", "pull_hub"]

_G = 9.80665  #: m/s^2 per g (the hub's IMU reports g, deg/s, uT)
_CPU = ("user", "sys", "nice", "idle", "iowait", "hirq", "sirq")


def attach_hub(rec: Sink, hub: Hub, name: str, sensors: Iterable[str] = ()) -> str:
    """``name``: the default ``hub`` (numbered), or the name of a link made with
    :meth:`Recorder.listener` (protocol ``ros4mat``) and given to ``Hub.connect(listeners=)``,
    so that CONNECT and CONNECT_ACK are recorded too."""
    link: RawLink | None = rec.links.get(name)
    if link is not None and link.decoder is not None:
        raise InvalidArgument(f"{name!r} is recorded already")
    if link is None:  # not listening since the handshake: from now on
        name = rec.unique_name(name)
        link = RawLink(rec, name, "ros4mat", url=hub.url, sensors=",".join(sensors))
        rec.links[name] = link
        hub.session.listeners.add(link)
        rec.on_close(lambda: hub.session.listeners.remove(link))
    link.decoder = HubDecoder(rec, name, hub)
    return name


class HubDecoder:
    """Data replies (writer thread) -> one message per sample, published at the sample's
    acquisition time on the host clock (the hub's time minus the client's offset estimate,
    as the client puts it on its own clock: Unix time unless ``Hub.connect(clock=...)``
    gave another). All samples of one reply share its receive time as their log time."""

    def __init__(self, rec: Sink, name: str, hub: Hub) -> None:
        self.rec, self.hub, self.name = rec, hub, name
        self._cids: dict[str, int] = {}
        #: a sink that takes the samples as dicts (a live ROS 2 one): no JSON, images' bytes
        self._direct: Callable[..., None] | None = getattr(rec, "write_sample", None)

    def _cid(self, topic: str, schema: str) -> int:
        cid = self._cids.get(topic)
        if cid is None:
            cid = self._cids[topic] = self.rec.channel(f"/{self.name}/{topic}", schema)
        return cid

    def __call__(self, direction: str, frame: bytes, ns: int) -> None:
        from robocli.devices.hub.decode import HEADER, body_of
        from robocli.protocols.ros4mat import MsgType

        if direction != "rx" or len(frame) < HEADER.size:
            return
        header = HEADER.unpack_from(frame, 0)
        mtype, error, n = header[0], header[1], header[3]
        if error or not n or mtype not in _HUB_HANDLERS:
            return
        _, body = body_of(frame)
        offset = self.hub.sync.offset or 0.0
        _HUB_HANDLERS[mtype](self, MsgType(mtype), body, n, ns, offset)

    def _put(self, topic: str, schema: str, message: dict[str, Any], ns: int, t: float,
             offset: float) -> None:  # fmt: skip
        publish = int((t - offset) * 1e9)
        message["timestamp"] = S.stamp(publish)
        if self._direct is not None:
            self._direct(self._cid(topic, schema), message, ns, publish)
        else:
            self.rec.write(self._cid(topic, schema), json_text(message).encode(), ns, publish)

    def fixed(self, mtype: Any, body: Any, n: int, ns: int, offset: float) -> None:
        from robocli.protocols.ros4mat import MsgType, record_dtype

        rec = np.frombuffer(body, dtype=record_dtype(mtype), count=n)
        f = {name: rec[name].tolist() for name in rec.dtype.names or ()}  # Python numbers
        frame_id = f"{self.name}/{mtype.name.lower()}"
        put = self._put
        for i, t in enumerate(f["t"]):
            if mtype == MsgType.ADC:
                put("adc", "robocli.Adc", {"channels": f["channels"][i]}, ns, t, offset)
            elif mtype == MsgType.IMU:
                put("imu", "robocli.Imu", {
                    "frame_id": frame_id,
                    "linear_acceleration": _xyz([v * _G for v in f["acc"][i]]),
                    "angular_velocity": _xyz([math.radians(v) for v in f["gyro"][i]]),
                    "magnetic_field": _xyz([v * 1e-6 for v in f["mag"][i]]),
                }, ns, t, offset)  # fmt: skip
            elif mtype == MsgType.GPS:
                fix = S.location_fix(0, frame_id, f["latitude"][i], f["longitude"][i],
                                     f["altitude"][i])  # fmt: skip
                put("gps", "foxglove.LocationFix", fix, ns, t, offset)
            elif mtype == MsgType.COMPUTER:
                put("sysinfo", "robocli.SysInfo", {
                    "cpu_temperature": f["cpu_temperature"][i], "load": f["unix_load"][i],
                    "cpu": dict(zip(_CPU, f["cpu_load"][i], strict=True)),
                    "memory": dict(zip(("used", "free", "buffers"), f["memory"][i], strict=True)),
                    "state": f["state"][i],
                }, ns, t, offset)  # fmt: skip
            else:  # BATTERY
                put("battery", "robocli.Battery", {
                    "voltage": f["vtotal"][i], "current": f["current"][i],
                    "cells": f["vcell"][i][: f["n_cells"][i]], "state": f["state"][i],
                    "state_of_charge": f["state_of_charge"][i],
                }, ns, t, offset)  # fmt: skip

    def laser(self, mtype: Any, body: Any, n: int, ns: int, offset: float) -> None:
        from robocli.protocols.ros4mat import record_dtype

        dtype = record_dtype(mtype)
        infos = np.frombuffer(body, dtype=dtype, count=n)
        pos = n * dtype.itemsize
        frame_id = f"{self.name}/laser"
        for info in infos:
            size = int(info["size_data"])
            ranges = np.frombuffer(body, dtype="<f4", count=size // 4, offset=pos).tolist()
            pos += size
            scan = S.laser_scan(0, frame_id, float(info["angle_min"]), float(info["angle_max"]),
                                ranges)  # fmt: skip
            self._put("laser", "foxglove.LaserScan", scan, ns, float(info["t"]), offset)

    def images(self, mtype: Any, body: Any, n: int, ns: int, offset: float) -> None:
        from robocli.protocols.ros4mat import MsgType, record_dtype

        dtype = record_dtype(mtype)
        view = memoryview(body)
        if mtype == MsgType.KINECT:
            infos = np.frombuffer(body, dtype=dtype, count=n)
            pos = n * dtype.itemsize
            for info in infos:
                for part, topic in (("rgb", "depth/rgb"), ("depth", "depth/image")):
                    pos = self._image(topic, info[part], view, pos, ns, offset,
                                      depth=part == "depth")  # fmt: skip
            return
        count = 2 * n if mtype == MsgType.WEBCAM_STEREO else n
        infos = np.frombuffer(body, dtype=dtype, count=count)
        pos = count * dtype.itemsize
        for k, info in enumerate(infos):
            topic = ("stereo/left", "stereo/right")[k % 2] if count != n else "camera"
            pos = self._image(topic, info, view, pos, ns, offset)

    def _image(self, topic: str, info: Any, view: memoryview, pos: int, ns: int, offset: float,
               depth: bool = False) -> int:  # fmt: skip
        size, width, height = int(info["size_data"]), int(info["width"]), int(info["height"])
        blob = view[pos : pos + size]
        frame_id = f"{self.name}/{topic.split('/')[0]}"
        if len(blob) != size:
            raise InvalidArgument(f"hub {topic}: image of {size} bytes past the reply's end")
        raw = self._direct is not None  # the bytes as they are, not base64
        if int(info["compression"]) != 0:
            msg = S.compressed_image(0, frame_id, blob, "jpeg", raw=raw)
            self._put(topic, "foxglove.CompressedImage", msg, ns, float(info["t"]), offset)
        else:
            encoding, step = ("mono16", width * 2) if depth else ("rgb8", width * 3)
            msg = S.raw_image(0, frame_id, width, height, encoding, step, blob, raw=raw)
            self._put(topic, "foxglove.RawImage", msg, ns, float(info["t"]), offset)
        return pos + size


def _xyz(v: list[float]) -> dict[str, float]:
    return {"x": v[0], "y": v[1], "z": v[2]}


def _hub_handlers() -> dict[int, Callable[..., None]]:
    from robocli.protocols.ros4mat import MsgType

    return {
        MsgType.ADC: HubDecoder.fixed, MsgType.IMU: HubDecoder.fixed,
        MsgType.GPS: HubDecoder.fixed, MsgType.COMPUTER: HubDecoder.fixed,
        MsgType.BATTERY: HubDecoder.fixed, MsgType.HOKUYO: HubDecoder.laser,
        MsgType.WEBCAM: HubDecoder.images, MsgType.WEBCAM_STEREO: HubDecoder.images,
        MsgType.KINECT: HubDecoder.images,
    }  # fmt: skip


_HUB_HANDLERS = _hub_handlers()


def pull_hub(hub: Hub, sensors: Iterable[str], poll_hz: float,
             done: Callable[[], bool]) -> None:  # fmt: skip
    """Pull each of ``sensors`` (already subscribed) ``poll_hz`` times a second until
    ``done()`` is true or the link fails (its error raises). A recorder added to ``hub``
    records every reply."""
    names = list(sensors)
    if not poll_hz > 0:
        raise InvalidArgument(f"poll_hz must be positive, not {poll_hz!r}")
    period = 1.0 / poll_hz
    due = time.monotonic()
    while not done():
        for sensor in names:
            hub.read(sensor)
        due += period
        now = time.monotonic()
        if due > now:
            time.sleep(min(due - now, period))
        else:
            due = now  # behind: pull again at once, without a burst to catch up
