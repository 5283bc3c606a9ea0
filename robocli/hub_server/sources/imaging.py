"""Simulated imaging sensors: camera, stereo pair, depth camera (Kinect), laser scanner.

The camera sees a synthetic moving scene (a scrolling gradient and a bouncing disc); the
stereo pair sees it with a horizontal disparity; the depth camera and the laser ray-cast the
Pioneer simulator's default world from a robot driving a circle in it. Images are RGB24 raw,
or JPEG at the requested quality when Pillow or OpenCV is installed (``robocli-robots[camera]``);
without either, a JPEG request is served raw and each frame says so (``compression`` 0 in its
``msgCam``, which the original client checks per frame).

Records hold the wire info record(s) (``info``) and fixed-size blob fields padded to the
largest image; :meth:`Source.blob_sizes` gives the bytes used.
"""

from __future__ import annotations

import importlib.util
import io
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from robocli.errors import InvalidArgument
from robocli.hub_server.sources.base import PeriodicSource, rate_param
from robocli.protocols.ros4mat import record_dtype
from robocli.sim.world import World

__all__ = [
    "CameraSource",
    "DepthSource",
    "LaserSource",
    "StereoSource",
    "jpeg_encoder",
    "robot_pose",
]

MAX_SIDE = (1600, 1200)


def jpeg_encoder() -> str | None:
    """``"pillow"`` or ``"opencv"``: what can encode JPEG here (None: raw images only)."""
    for module, name in (("PIL", "pillow"), ("cv2", "opencv")):
        if importlib.util.find_spec(module) is not None:
            return name
    return None


def encode_jpeg(image: npt.NDArray[np.uint8], quality: int, encoder: str) -> bytes:
    """An RGB image (H, W, 3) as JPEG bytes."""
    if encoder == "pillow":
        image_module: Any = importlib.import_module("PIL.Image")
        buf = io.BytesIO()
        image_module.fromarray(image).save(buf, format="JPEG", quality=int(quality))
        return buf.getvalue()
    cv2: Any = importlib.import_module("cv2")
    ok, data = cv2.imencode(".jpg", image[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(quality)])
    if not ok:
        raise InvalidArgument("OpenCV could not encode the frame as JPEG")
    return bytes(data)


def robot_pose(t: float) -> tuple[float, float, float]:
    """Where the simulated robot carrying the laser and depth camera is at time ``t``: on a
    1.5 m circle around (2, 0) in the default world, 0.25 m/s, facing forward."""
    phase = 0.25 / 1.5 * t
    return 2.0 + 1.5 * math.cos(phase), 1.5 * math.sin(phase), phase + math.pi / 2


_BASES: dict[tuple[int, int], npt.NDArray[np.uint8]] = {}


def scene(width: int, height: int, t: float, shift: int = 0) -> npt.NDArray[np.uint8]:
    """The synthetic scene at time ``t``: RGB (height, width, 3); ``shift`` moves the
    viewpoint right by that many pixels (a stereo pair's disparity). A red ramp scrolling
    right, a green vertical ramp, and a yellow disc moving on a Lissajous curve."""
    base = _BASES.get((width, height))
    if base is None:
        base = np.empty((height, width, 3), dtype=np.uint8)
        base[..., 1] = (np.arange(height) * 255.0 / max(1, height - 1)).astype(np.uint8)[:, None]
        base[..., 2] = 96
        if len(_BASES) > 16:
            _BASES.clear()
        _BASES[(width, height)] = base
    img: npt.NDArray[np.uint8] = base.copy()
    img[..., 0] = ((np.arange(width) + shift + 40.0 * t) % 256).astype(np.uint8)[None, :]
    r = min(width, height) / 8
    cx = (0.5 + 0.4 * math.sin(0.7 * t)) * width - shift
    cy = (0.5 + 0.4 * math.cos(0.9 * t)) * height
    x0, x1 = max(0, int(cx - r)), min(width, int(cx + r) + 1)
    y0, y1 = max(0, int(cy - r)), min(height, int(cy + r) + 1)
    if x0 < x1 and y0 < y1:
        xs = np.arange(x0, x1)[None, :]
        ys = np.arange(y0, y1)[:, None]
        img[y0:y1, x0:x1][(xs - cx) ** 2 + (ys - cy) ** 2 < r * r] = (250, 250, 40)
    return img


def _cam_dtype() -> np.dtype[Any]:
    return record_dtype("camera")


class _ImageSource(PeriodicSource):
    """Shared parameter handling of the camera-like sources."""

    MAX_RATE = 60.0
    DEFAULT_SIZE = (320, 240)
    KEYS = ("fps", "width", "height", "compression")  #: the params' names of these four

    def configure(self, params: Mapping[str, Any]) -> None:
        fps, width, height, quality = self.KEYS
        self.rate = rate_param(params, fps, 15.0, self.MAX_RATE)
        self.batch_rate = self.rate
        w, h = self._size(params.get(width), params.get(height))
        self.params = {"width": w, "height": h, "quality": self._quality(params.get(quality))}

    def _size(self, width: Any, height: Any) -> tuple[int, int]:
        w = int(width or self.DEFAULT_SIZE[0])
        h = int(height or self.DEFAULT_SIZE[1])
        if not (16 <= w <= MAX_SIDE[0] and 16 <= h <= MAX_SIDE[1]):
            raise InvalidArgument(f"width x height must be within 16..1600 x 16..1200, not {w}x{h}")
        return w, h

    def _quality(self, value: Any) -> int:
        q = int(value or 0)
        if not 0 <= q <= 100:
            raise InvalidArgument(f"compression (JPEG quality) must be 0..100, not {q}")
        return q if self.encoder is not None else 0

    def __init__(self) -> None:
        self.encoder = jpeg_encoder()
        super().__init__()

    def _fill(self, info: Any, blob: npt.NDArray[np.uint8], image: npt.NDArray[Any],
              t: float, quality: int) -> None:  # fmt: skip
        """Write one image (raw bytes, or JPEG when ``quality``) and its ``msgCam``."""
        h, w = image.shape[:2]
        channels = image.shape[2] if image.ndim == 3 else 1
        if quality and self.encoder is not None and image.dtype == np.uint8:
            data = np.frombuffer(encode_jpeg(image, quality, self.encoder), dtype=np.uint8)
            data = data[: len(blob)]
        else:
            data = image.reshape(-1).view(np.uint8)
            quality = 0
        blob[: len(data)] = data
        info["width"], info["height"], info["channels"] = w, h, channels
        info["size_data"], info["compression"], info["t"] = len(data), quality, t


class CameraSource(_ImageSource):
    """One camera (``paramsCamera``): fps, width x height, JPEG quality (0: raw)."""

    name = "camera"
    blobs = ("blob0",)

    def dtype(self) -> np.dtype[Any]:
        n = self.params["width"] * self.params["height"] * 3
        return np.dtype([("info", _cam_dtype()), ("blob0", np.uint8, (n,))])

    def sample(self, t: npt.NDArray[np.float64]) -> npt.NDArray[Any]:
        rec = np.zeros(len(t), dtype=self.dtype())
        w, h, q = self.params["width"], self.params["height"], self.params["quality"]
        for i, ti in enumerate(t):
            self._fill(rec["info"][i : i + 1], rec["blob0"][i], scene(w, h, ti), ti, q)
        return rec

    def blob_sizes(self, records: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
        return records["info"]["size_data"].astype(np.int64).reshape(-1, 1)

    def settings(self) -> dict[str, Any]:
        return {**super().settings(), "jpeg": self.encoder or "unavailable (raw only)"}


class StereoSource(_ImageSource):
    """A stereo pair (``paramsStereoCam``): left and right frames share one timestamp; the
    right one sees the scene :attr:`DISPARITY` pixels to the right."""

    name = "stereo"
    blobs = ("blob0", "blob1")
    DISPARITY = 8

    def dtype(self) -> np.dtype[Any]:
        n = self.params["width"] * self.params["height"] * 3
        return np.dtype(
            [("info", _cam_dtype(), (2,)), ("blob0", np.uint8, (n,)), ("blob1", np.uint8, (n,))]
        )

    def sample(self, t: npt.NDArray[np.float64]) -> npt.NDArray[Any]:
        rec = np.zeros(len(t), dtype=self.dtype())
        w, h, q = self.params["width"], self.params["height"], self.params["quality"]
        for i, ti in enumerate(t):
            info = rec["info"][i]
            self._fill(info[0:1], rec["blob0"][i], scene(w, h, ti), ti, q)
            self._fill(info[1:2], rec["blob1"][i], scene(w, h, ti, self.DISPARITY), ti, q)
        return rec

    def blob_sizes(self, records: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
        return records["info"]["size_data"].astype(np.int64).reshape(-1, 2)


class DepthSource(_ImageSource):
    """A depth camera (Kinect, ``paramsKinect``): RGB and 16-bit depth (mm) of the default
    world seen from the robot of :func:`robot_pose`; both images share one timestamp. Depth
    is planar (mm along the optical axis); walls fill the upper rows, the floor the lower."""

    name = "depth"
    KEYS = ("fps_rgb", "width_rgb", "height_rgb", "compression_rgb")
    blobs = ("blob0", "blob1")
    MAX_RATE = 30.0
    HFOV = math.radians(57.0)
    CAMERA_HEIGHT = 0.4  # m above the floor
    MAX_DEPTH = 8.0

    def __init__(self) -> None:
        self._world = World.default()
        super().__init__()

    def dtype(self) -> np.dtype[Any]:
        n = self.params["width"] * self.params["height"]
        return np.dtype(
            [
                ("info", record_dtype("kinect")),
                ("blob0", np.uint8, (n * 3,)),
                ("blob1", np.uint8, (n * 2,)),
            ]
        )

    def depth_image(self, t: float) -> npt.NDArray[np.uint16]:
        """The depth image (mm, 0 = no reading) at time ``t``."""
        w, h = self.params["width"], self.params["height"]
        x, y, th = robot_pose(t)
        focal = (w / 2) / math.tan(self.HFOV / 2)
        cols = np.arange(w) - (w - 1) / 2
        bearing = -np.arctan(cols / focal)
        ranges = self._world.cast(np.full(w, x), np.full(w, y), th + bearing, self.MAX_DEPTH)
        wall = ranges * np.cos(bearing)
        rows = np.arange(h) - (h - 1) / 2
        below = np.maximum(rows, 1e-6)[:, None]
        floor = self.CAMERA_HEIGHT * focal / below  # planar distance of the floor seen
        depth = np.where(rows[:, None] > 0, np.minimum(floor, wall[None, :]), wall[None, :])
        depth = np.where(depth >= self.MAX_DEPTH, 0.0, depth)
        return np.asarray(np.round(depth * 1000.0), dtype=np.uint16)

    def sample(self, t: npt.NDArray[np.float64]) -> npt.NDArray[Any]:
        rec = np.zeros(len(t), dtype=self.dtype())
        w, h, q = self.params["width"], self.params["height"], self.params["quality"]
        for i, ti in enumerate(t):
            info = rec["info"][i : i + 1]
            self._fill(info["rgb"], rec["blob0"][i], scene(w, h, ti), ti, q)
            depth = self.depth_image(ti)
            self._fill(info["depth"], rec["blob1"][i], depth.astype("<u2"), ti, 0)
        return rec

    def blob_sizes(self, records: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
        info = records["info"]
        return np.stack([info["rgb"]["size_data"], info["depth"]["size_data"]], axis=1).astype(
            np.int64
        )


class LaserSource(PeriodicSource):
    """A Hokuyo UTM-30LX-like scanner (1081 beams over 270 deg, 0.1..30 m) on the robot of
    :func:`robot_pose`, ray-cast in the Pioneer simulator's default world. A beam with no
    return reads 0 (below ``range_min``)."""

    name = "laser"
    blobs = ("blob0",)
    MAX_RATE = 40.0
    BEAMS = 1081
    ANGLE_MIN, ANGLE_MAX = math.radians(-135.0), math.radians(135.0)
    RANGE_MIN, RANGE_MAX = 0.1, 30.0
    NOISE = 0.01

    def __init__(self, seed: int = 5) -> None:
        self._world = World.default()
        self._rng = np.random.default_rng(seed)
        self._angles = np.linspace(self.ANGLE_MIN, self.ANGLE_MAX, self.BEAMS)
        super().__init__()

    def configure(self, params: Mapping[str, Any]) -> None:
        self.rate = rate_param(params, "freq_acquisition", 10.0, self.MAX_RATE)
        self.batch_rate = self.rate
        self.params = {"beams": self.BEAMS}

    def dtype(self) -> np.dtype[Any]:
        return np.dtype([("info", record_dtype("hokuyo")), ("blob0", np.uint8, (self.BEAMS * 4,))])

    def scan(self, t: float) -> npt.NDArray[np.float32]:
        """The ranges (m) of one scan at time ``t``."""
        ranges = _cast(self._world, robot_pose(t), self._angles, self.RANGE_MAX)
        ranges = ranges + self._rng.normal(0, self.NOISE, len(ranges))
        ok = np.isfinite(ranges) & (ranges >= self.RANGE_MIN)
        return np.where(ok, ranges, 0.0).astype("<f4")

    def sample(self, t: npt.NDArray[np.float64]) -> npt.NDArray[Any]:
        rec = np.zeros(len(t), dtype=self.dtype())
        info = rec["info"]
        info["angle_min"], info["angle_max"] = self.ANGLE_MIN, self.ANGLE_MAX
        info["angle_increment"] = (self.ANGLE_MAX - self.ANGLE_MIN) / (self.BEAMS - 1)
        info["time_increment"] = 1.0 / 40.0 / 1440.0
        info["range_min"], info["range_max"] = self.RANGE_MIN, self.RANGE_MAX
        info["t"], info["size_data"] = t, self.BEAMS * 4
        for i, ti in enumerate(t):
            rec["blob0"][i] = self.scan(ti).view(np.uint8)
        return rec

    def blob_sizes(self, records: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
        return records["info"]["size_data"].astype(np.int64).reshape(-1, 1)


def _cast(
    world: World, pose: tuple[float, float, float], angles: npt.NDArray[np.float64], top: float
) -> npt.NDArray[np.float64]:
    """Ranges along ``angles`` (relative to the pose's heading), ``inf`` beyond ``top``:
    the Pioneer simulator's laser model (:func:`robocli.sim.laser.cast`) when present."""
    try:
        from robocli.sim.laser import cast
    except ImportError:  # an older tree without the laser model: the same ray cast
        x, y, th = pose
        n = len(angles)
        hit = world.cast(np.full(n, x), np.full(n, y), angles + th, math.inf)
        return np.where(hit <= top, hit, math.inf)
    return cast(world, pose, angles, top)
