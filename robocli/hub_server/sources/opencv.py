"""A real camera through OpenCV (the optional extra ``robocli-robots[camera]``).

Serves ``camera`` (ros4mat 0x24) from ``/dev/videoN`` (the subscribe's ``id``) at the
requested frame rate and size (frames of another size are resized), raw RGB or JPEG at the
requested quality. Each frame is stamped when it is read, on the hub's clock.
"""

from __future__ import annotations

import importlib.util
from typing import Any

import numpy as np

from robocli.errors import DeviceError
from robocli.hub_server.sources.base import Batch
from robocli.hub_server.sources.imaging import CameraSource

__all__ = ["OpenCvCameraSource", "opencv_available"]


def _cv2() -> Any:
    return importlib.import_module("cv2")


def opencv_available() -> bool:
    """Whether OpenCV (``cv2``) can be imported here."""
    return importlib.util.find_spec("cv2") is not None


class OpenCvCameraSource(CameraSource):
    """``/dev/video<id>`` through ``cv2.VideoCapture``."""

    simulated = False

    def __init__(self) -> None:
        self._capture: Any = None
        super().__init__()
        self.encoder = "opencv"

    def start(self, t0: float) -> None:
        cv2 = _cv2()
        self.stop()
        device = int(self.params.get("id", 0))
        capture = cv2.VideoCapture(device)
        if not capture.isOpened():
            raise DeviceError(f"camera /dev/video{device} cannot be opened")
        capture.set(cv2.CAP_PROP_FRAME_WIDTH, self.params["width"])
        capture.set(cv2.CAP_PROP_FRAME_HEIGHT, self.params["height"])
        capture.set(cv2.CAP_PROP_FPS, self.rate)
        self._capture = capture

    def configure(self, params: Any) -> None:
        super().configure(params)
        self.params["id"] = int(params.get("id", 0) or 0)

    def poll(self, now: float) -> Batch:
        cv2 = _cv2()
        capture = self._capture
        if capture is None:
            return self.empty()
        ok, frame = capture.read()
        if not ok:
            raise DeviceError("the camera returned no frame")
        t = self.clock()
        w, h = self.params["width"], self.params["height"]
        if frame.shape[1] != w or frame.shape[0] != h:
            frame = cv2.resize(frame, (w, h))
        rgb = np.ascontiguousarray(frame[..., ::-1])
        rec = np.zeros(1, dtype=self.dtype())
        self._fill(rec["info"][0:1], rec["blob0"][0], rgb, t, self.params["quality"])
        return np.array([t]), rec

    def stop(self) -> None:
        if self._capture is not None:
            self._capture.release()
            self._capture = None
