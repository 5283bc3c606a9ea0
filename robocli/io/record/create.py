"""An iRobot Create 2's channels: its stream frames -> pose, odom -> base_link, state (see
:mod:`.sources` for the topics); its OI bytes both ways go to the raw channels (protocol
``create-oi``: commands on ``tx``, stream frames on ``rx``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from robocli.devices.create.client import CreateOdometry, state_of
from robocli.errors import InvalidArgument, ProtocolError
from robocli.io import schemas as S
from robocli.io.record.links import RawLink, Sink, TopicDecoder, json_text, new_link
from robocli.protocols import create_oi as oi

if TYPE_CHECKING:
    from robocli.devices.create import Create

__all__ = ["CreateDecoder", "attach_create"]


def attach_create(rec: Sink, robot: Create, name: str | None) -> str:
    """``name``: the default ``create`` (numbered), or the name of a link made with
    :meth:`Recorder.listener` (protocol ``create-oi``) and given to
    ``Create.connect(listeners=)``, so that the start and the stream request are recorded
    (a ``create-oi`` link decodes from its first frame: the pose is a sum of the distances
    and angles since)."""
    link: RawLink | None = rec.links.get(name) if name is not None else None
    if link is None:  # not listening since the connection: from now on
        name = rec.unique_name(name or "create")
        link = new_link(rec, name, "create-oi", url=robot.url)
        link.decoder = CreateDecoder(rec, name)
        robot.add_listener(link)
        rec.on_close(lambda: robot.remove_listener(link))
    decoder = link.decoder
    if not isinstance(decoder, CreateDecoder) or decoder.claimed:
        raise InvalidArgument(f"{name!r} is recorded already, or not a create-oi link")
    decoder.claimed = True
    assert name is not None
    return name


class CreateDecoder(TopicDecoder):
    """Stream frames (writer thread) -> ``pose`` (PoseInFrame in ``NAME/odom``), ``tf``
    (odom -> ``NAME/base_link``) and ``state`` (robocli.create.State). Keeps its own
    odometry, so that every recorded pose belongs to the frame it was decoded from. A frame
    that does not decode is counted (:attr:`bad_frames`) and skipped."""

    def __init__(self, rec: Sink, name: str) -> None:
        super().__init__(rec, name, ("pose", "tf", "state"))
        self.claimed = False  #: a device was added on it (a link is recorded once)
        self.odo = CreateOdometry()
        self.frames = self.bad_frames = 0
        self.odom, self.base = f"{name}/odom", f"{name}/base_link"

    def __call__(self, direction: str, payload: bytes, ns: int) -> None:
        if direction != "rx":
            return
        fields: dict[str, int] = {}
        try:
            for _, values in oi.parse_stream(payload):
                fields.update(values)
        except ProtocolError:
            self.bad_frames += 1
            return
        self.frames += 1
        pose = self.odo.update(fields.get("distance", 0), fields.get("angle", 0))
        st = state_of(fields, ns / 1e9, pose, self.frames)
        quat = S.quaternion_z(st.th)
        xyz = {"x": st.x, "y": st.y, "z": 0.0}
        stamp = S.stamp(ns)
        w = self.rec.write
        w(self._cid("pose", "foxglove.PoseInFrame"), json_text({
            "timestamp": stamp, "frame_id": self.odom,
            "pose": {"position": xyz, "orientation": quat}}).encode(), ns)  # fmt: skip
        w(self._cid("tf", "foxglove.FrameTransform"),
          json_text(S.frame_transform(ns, self.odom, self.base, (st.x, st.y, 0.0), quat))
          .encode(), ns)  # fmt: skip
        state = {
            "timestamp": stamp, "x": st.x, "y": st.y, "th": st.th,
            "bump_left": st.bump_left, "bump_right": st.bump_right,
            "wheel_drop_left": st.wheel_drop_left, "wheel_drop_right": st.wheel_drop_right,
            "voltage": st.voltage, "current": st.current, "charge": st.charge,
            "capacity": st.capacity, "charging_state": st.charging_state, "mode": st.mode,
            "frame_count": self.frames,
        }  # fmt: skip
        w(self._cid("state", "robocli.create.State"), json_text(state).encode(), ns)
