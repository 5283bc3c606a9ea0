"""The simulated Hokuyo scanners' fixed data (:class:`HokuyoModel`) and their measurement in a
:class:`~robocli.sim.world.World` (:func:`measure`).

Values from ``docs/protocols/scip2.md`` section 4 (PP), section 3 (VV/II of the URG-04LX).
Decisions where the sources leave a fact uncertain:

* the USB UTM-30LX reports ``MODL:UTM-30LX``; the UST-10LX reports ``MODL:UST-10LX``;
* error codes on the wire for a ray with no return (beyond DMAX, or nothing hit) and for a
  hit nearer than DMIN: URG-04LX 0 (no return, "possibly object at 22 m") and 1 (low
  intensity); UTM-30LX and UST-10LX 1 (no object) and 2 (too near). The UST sentinel values
  65533-65535 of one weak source are not used;
* steps 0..AMIN-1 (URG-04LX: 0..43) may be requested and read code 19 ("non-measurable
  step"); an end step above AMAX is refused with status 04;
* the state commands ``%ST``/``%SL`` (hokuyolx's UST/UTM family) are served by the UTM-30LX
  (which stands for the UTM-30LX-EW when served over TCP) and the UST-10LX; the URG-04LX
  answers them ``0E``;
* the URG-04LX profile boots in SCIP 1.1 (``classic=True``, the default for that model) and
  needs the ``SCIP2.0`` switch; the UTM and UST boot in SCIP 2.0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from robocli.sim.laser import cast
from robocli.sim.world import World

__all__ = ["MODELS", "URG_04LX", "UST_10LX", "UTM_30LX", "HokuyoModel", "measure"]

IntArray = npt.NDArray[np.int64]

NON_MEASURABLE = 19  #: URG-04LX code for a step outside [AMIN, AMAX]


@dataclass(frozen=True)
class HokuyoModel:
    """One scanner model: identity strings, PP parameters, link and error codes."""

    name: str
    vv: tuple[tuple[str, str], ...]
    modl: str
    dmin: int  #: mm
    dmax: int  #: mm
    ares: int  #: steps per full turn
    amin: int
    amax: int
    afrt: int
    rpm: int
    bps: int = 115200
    intensity: bool = True  #: GE/ME supported
    rt: bool = True  #: RT supported
    scip11: bool = False  #: boots in SCIP 1.1
    state_commands: bool = True  #: ``%ST``/``%SL`` (UST and UTM-30LX-EW firmware)
    code_no_return: int = 1
    code_too_near: int = 2
    tcp_port: int = 10940

    @property
    def period(self) -> float:
        """Seconds per scan (one turn)."""
        return 60.0 / self.rpm

    @property
    def steps(self) -> int:
        """Measured steps AMIN..AMAX."""
        return self.amax - self.amin + 1

    def angles(self, steps: npt.ArrayLike) -> npt.NDArray[np.float64]:
        """Angle (rad, counter-clockwise, 0 ahead) of each step."""
        s = np.asarray(steps, dtype=np.float64)
        out: npt.NDArray[np.float64] = (s - self.afrt) * (2.0 * math.pi / self.ares)
        return out

    def pp(self) -> list[str]:
        """The PP reply's ``KEY:value`` lines."""
        return [
            f"MODL:{self.modl}", f"DMIN:{self.dmin}", f"DMAX:{self.dmax}",
            f"ARES:{self.ares}", f"AMIN:{self.amin}", f"AMAX:{self.amax}",
            f"AFRT:{self.afrt}", f"SCAN:{self.rpm}",
        ]  # fmt: skip

    def ii(self, *, laser: bool, mode: str, time_ms: int) -> list[str]:
        """The II reply's ``KEY:value`` lines for the device's state now."""
        stamp = f"{time_ms & 0xFFFFFF:06X}"
        return [
            f"MODL:{self.modl}", f"LASR:{'ON' if laser else 'OFF'}",
            f"SCSP:Initial({self.rpm}[rpm])<-Default setting by user",
            f"MESM:{mode}", f"SBPS:{self.bps}[bps]<-Default setting by user",
            f"TIME:{stamp}", "STAT:Sensor works well.",
        ]  # fmt: skip


def _vv(prod: str, firm: str, seri: str) -> tuple[tuple[str, str], ...]:
    return (
        ("VEND", "Hokuyo Automatic Co.,Ltd."), ("PROD", prod), ("FIRM", firm),
        ("PROT", "SCIP 2.0"), ("SERI", seri),
    )  # fmt: skip


#: URG-04LX: the wiki identity (docs/protocols/scip2.md section 3), 682 steps, 100 ms, USB/RS-232.
URG_04LX = HokuyoModel(
    name="urg-04lx",
    vv=_vv("SOKUIKI Sensor URG-04LX", "3.1.00(18/Jan./2007)", "H0614967"),
    modl="URG-04LX(Hokuyo Automatic Co.,Ltd.)",
    dmin=20, dmax=5600, ares=1024, amin=44, amax=725, afrt=384, rpm=600, bps=19200,
    intensity=False, rt=False, scip11=True, code_no_return=0, code_too_near=1,
    state_commands=False,
)  # fmt: skip
#: UTM-30LX (USB): 1081 steps over 270 deg, 25 ms.
UTM_30LX = HokuyoModel(
    name="utm-30lx",
    vv=_vv("SOKUIKI Sensor TOP-URG UTM-30LX", "1.1.0(2009-11-16)", "H0000001"),
    modl="UTM-30LX", dmin=23, dmax=60000, ares=1440, amin=0, amax=1080, afrt=540, rpm=2400,
)  # fmt: skip
#: UST-10LX (Ethernet, TCP 10940): 1081 steps over 270 deg, 25 ms, 30 m.
UST_10LX = HokuyoModel(
    name="ust-10lx",
    vv=_vv("SOKUIKI Sensor UST-10LX", "1.0.0(2014-01-01)", "H0000002"),
    modl="UST-10LX", dmin=20, dmax=30000, ares=1440, amin=0, amax=1080, afrt=540, rpm=2400,
)  # fmt: skip

MODELS: dict[str, HokuyoModel] = {m.name: m for m in (URG_04LX, UTM_30LX, UST_10LX)}


def measure(
    model: HokuyoModel, world: World, pose: tuple[float, float, float], *, last_step: int
) -> IntArray:
    """Wire values of steps ``0..last_step`` from ``pose`` (x, y m; th rad) in ``world``:
    ranges in whole millimetres (rounded from the exact ray cast), error codes where the ray
    has no return, hits nearer than DMIN, and code 19 outside [AMIN, AMAX]."""
    steps = np.arange(last_step + 1)
    hit = cast(world, pose, model.angles(steps), math.inf)
    mm = np.where(np.isfinite(hit), np.rint(hit * 1000.0), -1.0)
    out = mm.astype(np.int64)
    out[(mm < 0) | (mm > model.dmax)] = model.code_no_return
    out[(mm >= 0) & (mm < model.dmin)] = model.code_too_near
    out[(steps < model.amin) | (steps > model.amax)] = NON_MEASURABLE
    return out
