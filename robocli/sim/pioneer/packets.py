"""The server packets of the simulated Pioneer's firmware: SIP, CONFIG, encoder, IO and
battery, built from the model and the firmware's state (:class:`ServerPackets`, a part of
:class:`~robocli.sim.pioneer.session.ArcosController`)."""

from __future__ import annotations

import math
from typing import Any

from robocli.protocols.arcos import (
    CONFIG,
    FLAG_ESTOP,
    FLAG_MOTORS_ON,
    FLAG_SONAR_MASK,
    PacketType,
    encode_server,
    encode_sip_body,
    frame,
)
from robocli.robots.pioneer import RobotParams
from robocli.sim.pioneer.model import NUM_BUMPERS, TICKS_PER_MM, PioneerModel, clamp

__all__ = ["ServerPackets", "sonar_batch"]

_CONFIG_FIELDS = [str(sc.name) for sc in CONFIG.subcons]
_CONFIG_OPTIONAL = _CONFIG_FIELDS[_CONFIG_FIELDS.index("powerbot_charge_threshold") + 1 :]


def _int16(v: float) -> int:
    return int(clamp(round(v), -32768, 32767))


def sonar_batch(n_total: int, cursor: int, k_max: int) -> tuple[list[int], int]:
    """Indices of the sonars to report in one SIP (at most ``k_max``) and the next cursor:
    all of them when they fit, else the next ``k_max`` in rotation."""
    if n_total <= k_max:
        return list(range(n_total)), 0
    idx = [(cursor + i) % n_total for i in range(k_max)]
    return idx, (cursor + k_max) % n_total


class ServerPackets:
    """Builds the server packets; the controller's lock is held by the caller. The attributes
    below are the firmware state the packets report (set by the controller)."""

    model: PioneerModel
    params: RobotParams
    name: str
    subtype: str
    sip_ms: float
    watchdog_s: float
    report_soc: bool
    sonar_on: bool
    digout: int
    _digin: int
    _anport: int
    _sonar_cursor: int
    _sonar_k_max: int
    _config_cache: tuple[tuple[float, ...], bytes] | None

    def _odom_raw(self) -> tuple[int, int, int]:
        p, (ox, oy, oth) = self.params, self.model.odom
        x = round(ox * 1000.0 / p.dist_conv) & 0x7FFF
        y = round(oy * 1000.0 / p.dist_conv) & 0x7FFF
        th = (round(oth / p.angle_conv) + 2048) % 4096 - 2048
        return x, y, th

    def _sip_tail(self) -> dict[str, Any]:
        r = self.model
        volts = round(r.volts * 10.0)
        return {
            "io": {"grip_state": 0, "anport": self._anport, "analog": 0,
                   "digin": self._digin, "digout": self.digout},
            "battery_x10": int(clamp(volts, 0, 65535)), "charge_state": 0,
            "rotvel": _int16(math.degrees(r.w) * 10.0), "fault_flags": 0, "latvel": 0,
            "temperature": -127,
            "state_of_charge": round(r.state_of_charge) if self.report_soc else 0,
        }  # fmt: skip

    def _sip(self) -> bytes:
        r, p = self.model, self.params
        x, y, th = self._odom_raw()
        left, right = r.wheel_speeds()
        flags = (FLAG_MOTORS_ON if r.motors else 0) | (FLAG_ESTOP if r.estop else 0)
        sonar: list[tuple[int, int]] = []
        if self.sonar_on:
            flags |= FLAG_SONAR_MASK
            idx, self._sonar_cursor = sonar_batch(
                len(r.sonar), self._sonar_cursor, self._sonar_k_max
            )
            conv = 1000.0 / p.range_conv
            sonar = [(i, int(clamp(round(r.sonar[i] * conv), 0, 65535))) for i in idx]
        body = {
            "x": x, "y": y, "th": th,
            "lvel": _int16(left * 1000.0 / p.vel_conv), "rvel": _int16(right * 1000.0 / p.vel_conv),
            "battery": int(clamp(round(r.volts * 10.0), 0, 255)),
            "stall_bumpers": r.stall_bits | r.bumper_bits, "control": 0, "flags": flags,
            "compass": 0, "sonar": sonar, **self._sip_tail(),
        }  # fmt: skip
        return frame(bytes((PacketType.SIP,)) + encode_sip_body(body))

    def _config_packet(self) -> bytes:
        lim = self.model.limits
        key = (lim.trans_vel_max, lim.trans_accel, lim.trans_decel,
               lim.rot_vel_max, lim.rot_accel, lim.rot_decel)  # fmt: skip
        cache = self._config_cache
        if cache is not None and cache[0] == key:
            return cache[1]  # the only fields that change are the per-session limits
        p, deg = self.params, math.degrees
        body: dict[str, Any] = {name: 0 for name in _CONFIG_FIELDS}
        body.update(
            robot_type="Pioneer", subtype=self.subtype, serial="SIM", name=self.name,
            firmware="robocli", rotvel_top=round(deg(p.max_rot_velocity)),
            transvel_top=round(p.max_velocity * 1000), rotacc_top=500, transacc_top=2000,
            pwm_max=400, sip_cycle=int(round(self.sip_ms)), front_sonar=1,
            rear_sonar=1 if len(p.sonar) > 8 else 0,
            watchdog=min(65535, round(self.watchdog_s * 1000)),
            rotvel_max=round(deg(lim.rot_vel_max)), transvel_max=round(lim.trans_vel_max * 1000),
            rot_accel=round(deg(lim.rot_accel)), rot_decel=round(deg(lim.rot_decel)),
            trans_accel=round(lim.trans_accel * 1000), trans_decel=round(lim.trans_decel * 1000),
            front_bumps=NUM_BUMPERS, rear_bumps=NUM_BUMPERS, reset_baud=2,
            ticks_mm=TICKS_PER_MM, latvel_top=0, latacc_top=0,
        )  # fmt: skip
        body.update(dict.fromkeys(_CONFIG_OPTIONAL))
        # construct takes ~0.3 ms to build it: rebuild only when a limit changed
        self._config_cache = (key, encode_server(PacketType.CONFIG, body))
        return self._config_cache[1]

    def _encoder_packet(self) -> bytes:
        left, right = self.model.encoder_ticks()
        return encode_server(PacketType.ENCODER, {"left": left, "right": right})

    def _io_packet(self) -> bytes:
        bumps = self.model.bumper_bits
        digin = [self._digin, (bumps >> 8) & 0xFF, bumps & 0xFF, 0]
        return encode_server(
            PacketType.IO, {"digin": digin, "digout": [self.digout], "analog": [0] * 8}
        )

    def _battery_packet(self) -> bytes:
        soc = round(self.model.state_of_charge)
        data = bytes((0, 0, 0, soc, soc))
        return encode_server(
            PacketType.BATTERY, {"count": 1, "bytes_per_battery": len(data), "data": data}
        )
