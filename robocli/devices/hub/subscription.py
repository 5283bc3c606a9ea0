"""The SUBSCRIBE request's body, as the original MATLAB client builds it: the settings of
each sensor (rates, buffer, the driver's batch rate, ADC channels, camera resolution,
quality and regions of interest), checked before anything is sent.

Part of the hub client (:mod:`robocli.devices.hub.client`, which re-exports
:func:`subscribe_body`, :func:`resolution` and :func:`raw_frame_bytes`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from robocli.errors import InvalidArgument
from robocli.protocols.ros4mat import (
    MAX_BODY_SIZE,
    PARAMS,
    MsgType,
    adc_freq_send_default,
    sensor_type,
)

__all__ = ["raw_frame_bytes", "resolution", "subscribe_body", "subscribe_request"]

#: Sensors whose subscribe params carry a ``freq_send`` (the driver's batch rate).
_WITH_FREQ_SEND = (MsgType.ADC, MsgType.IMU, MsgType.GPS, MsgType.BATTERY)
_CAMERAS = (MsgType.WEBCAM, MsgType.WEBCAM_STEREO, MsgType.KINECT, MsgType.KINECT_DEPTH)


def _u16(name: str, value: Any, low: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InvalidArgument(f"{name} must be a number, not {value!r}")
    if int(value) != value or not low <= value <= 0xFFFF:
        raise InvalidArgument(f"{name} must be an integer in {low}..65535, not {value!r}")
    return int(value)


def resolution(text: str) -> tuple[int, int]:
    """The original client's rule: ``'640x480'`` -> width ⌊640/20⌋·20 clamped to 160..1600,
    height 3/4 of it (4:3 only)."""
    head = text.lower().split("x", 1)[0].strip()
    digits = ""
    for ch in head:
        if not ch.isdigit():
            break
        digits += ch
    width = min(1600, max(160, (int(digits or 0) // 20) * 20))
    return width, width * 3 // 4


def _camera_params(kind: MsgType, fps: int, params: dict[str, Any]) -> dict[str, Any]:
    res = params.pop("resolution", None)
    width, height = resolution(res) if res is not None else (320, 240)
    width = _u16("width", params.pop("width", width))
    height = _u16("height", params.pop("height", height))
    quality = _u16("quality", params.pop("quality", 0))
    if quality > 100:
        raise InvalidArgument(f"quality must be 0 (raw) or 1..100 (JPEG), not {quality}")
    roi = params.pop("roi", None)
    if kind == MsgType.WEBCAM:
        return {
            "fps": fps, "width": width, "height": height, "id": params.pop("id", 0),
            "compression": quality, "exposure": params.pop("exposure", 300),
            "use_roi": int(roi is not None), "roi": list(roi or (0, 0, 0, 0)),
        }  # fmt: skip
    if kind == MsgType.WEBCAM_STEREO:
        roi_right = params.pop("roi_right", None)
        return {
            "fps": fps, "width": width, "height": height,
            "id_left": params.pop("id_left", 0), "id_right": params.pop("id_right", 1),
            "compression": quality,
            "exposure_left": params.pop("exposure_left", 300),
            "exposure_right": params.pop("exposure_right", 300),
            "use_roi": int(roi is not None),
            "roi_left": list(roi or (0, 0, 0, 0)), "roi_right": list(roi_right or roi or (0,) * 4),
        }  # fmt: skip
    roi_rgb = params.pop("roi_rgb", None)
    return {  # the original client always sends send_rgb = send_depth = fps_depth = 0
        "fps_rgb": fps, "width_rgb": width, "height_rgb": height,
        "send_rgb": params.pop("send_rgb", 0), "id": params.pop("id", 0),
        "send_depth": params.pop("send_depth", 0), "fps_depth": params.pop("fps_depth", 0),
        "compression_rgb": quality, "use_roi_depth": int(roi is not None),
        "roi_depth": list(roi or (0,) * 4), "use_roi_rgb": int(roi_rgb is not None),
        "roi_rgb": list(roi_rgb or (0,) * 4),
    }  # fmt: skip


def subscribe_body(
    sensor: str | int,
    rate: float | None = None,
    *,
    buffer: int | None = None,
    poll: int | None = None,
    **params: Any,
) -> dict[str, Any]:
    """The SUBSCRIBE body the original client sends (for :func:`encode_request`).

    ``rate`` None: a silent subscribe (join the current settings). ``buffer`` defaults to
    ``rate`` (one second); ``poll`` is the driver's batch rate in Hz, an integer 0..65535
    (``freqSend`` of adc, imu, gps, battery: default ⌊rate/4 + 10⌋, an explicit value is
    clamped to ``rate``). ``params``: ``channels`` (ADC
    mask, default 0xFF); cameras ``resolution='640x480'`` or ``width``/``height``, ``id``,
    ``quality`` (0 raw, 1..100 JPEG), ``exposure``, ``roi``; stereo ``id_left``/``id_right``,
    ``exposure_left``/``exposure_right``; Kinect ``send_rgb``, ``send_depth``,
    ``fps_depth``, ``roi_rgb``.
    """
    kind = sensor_type(sensor)
    if kind not in PARAMS:
        raise InvalidArgument(f"sensor: {kind.name} cannot be subscribed to")
    if rate is None:
        if params or buffer is not None or poll is not None:
            raise InvalidArgument("rate: a silent subscribe (no rate) takes no other setting")
        return {"sensor": kind, "silent": 1, "buffer_size": 0, "params": None}
    freq = _u16("rate", rate, 1)
    size = freq if buffer is None else int(buffer)
    if isinstance(buffer, bool) or not 1 <= size <= 0xFFFFFFFF:
        raise InvalidArgument(f"buffer must be a positive number of samples, not {buffer!r}")
    extra = dict(params)
    values: dict[str, Any]
    if kind in _CAMERAS:
        values = _camera_params(kind, freq, extra)
    else:
        values = {"freq_acquisition": freq}
        if kind in _WITH_FREQ_SEND:
            send = adc_freq_send_default(freq) if poll is None else min(_u16("poll", poll), freq)
            values["freq_send"] = send
        if kind == MsgType.ADC:
            mask = _u16("channels", extra.pop("channels", 0xFF))
            if not 1 <= mask <= 0xFF:  # the CLI's rule too: a mask selects some channel
                raise InvalidArgument(
                    f"channels must be an 8-bit mask with a channel set (1..0xff), not {mask:#x}"
                )
            values["channels"] = mask
    if extra:
        raise InvalidArgument(f"{next(iter(extra))}: not a setting of {kind.name.lower()}")
    return {"sensor": kind, "silent": 0, "buffer_size": size, "params": values}


def raw_frame_bytes(body: Mapping[str, Any]) -> int:
    """Bytes one raw camera sample takes in a reply (0: not a raw camera subscription)."""
    p = body.get("params")
    kind = body["sensor"]
    if not isinstance(p, Mapping) or kind not in _CAMERAS:
        return 0
    if kind == MsgType.KINECT or kind == MsgType.KINECT_DEPTH:
        if p["compression_rgb"]:
            return 0
        return int(p["width_rgb"]) * int(p["height_rgb"]) * 5 + 44
    if p["compression"]:
        return 0
    one = int(p["width"]) * int(p["height"]) * 3 + 22
    return 2 * one if kind == MsgType.WEBCAM_STEREO else one


def subscribe_request(
    name: str,
    rate: float | None = None,
    *,
    buffer: int | None = None,
    poll: int | None = None,
    **params: Any,
) -> dict[str, Any]:
    """The body :meth:`Hub.subscribe <robocli.devices.hub.client.Hub.subscribe>` sends:
    :func:`subscribe_body`, refusing ``kinect_ir`` (ros4mat has no pull for it), and with a
    raw camera's default buffer cut to what one reply holds (an explicit one that does not
    fit is refused)."""
    if sensor_type(name) == MsgType.KINECT_DEPTH:
        raise InvalidArgument(
            f"sensor: {name!r} (0x28) has no data pull in ros4mat and no hub serves it; "
            "subscribe to 'kinect' (alias 'depth') for RGB and depth"
        )
    body = subscribe_body(name, rate, buffer=buffer, poll=poll, **params)
    frame = raw_frame_bytes(body)
    if frame and frame * body["buffer_size"] > MAX_BODY_SIZE:
        fits = max(1, MAX_BODY_SIZE // frame)
        if buffer is not None:
            raise InvalidArgument(
                f"buffer: {buffer} raw frames of {frame} bytes exceed one reply's "
                f"{MAX_BODY_SIZE >> 20} MiB; at most {fits}"
            )
        body["buffer_size"] = fits  # the default (1 s) would not fit in one reply
    return body
