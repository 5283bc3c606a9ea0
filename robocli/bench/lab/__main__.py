"""``python -m robocli.bench.lab``: run the lab bench at several sizes and front-ends, print
the table (and write the figures as JSON with ``--json``). Root only; a machine where
network namespaces cannot be made is said so in one line (exit 0 with ``--skip-ok``, else 1).

    sudo .venv/bin/python -m robocli.bench.lab --sizes 1x1,2x4,4x8 --seconds 10
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
from typing import Any

from robocli.bench.lab.bench import (
    TARGET_HUB_CORES,
    TARGET_P99_S,
    TARGET_UPLINK_RATIO,
    LabRun,
    run_lab,
)
from robocli.bench.lab.netns import LabError, unavailable_reason
from robocli.errors import RobocliError

MODES = ("tcp", "zenoh")


def zenoh_missing() -> str | None:
    """Why the Zenoh front-end cannot run here (one line), or None."""
    import importlib.util

    if importlib.util.find_spec("zenoh") is None:
        return "eclipse-zenoh is not installed (pip install 'robocli-robots[zenoh]')"
    if importlib.util.find_spec("robocli.hub.frontends.zenoh") is None:
        return "this robocli has no Zenoh front-end for the hub (serve --zenoh)"
    return None


def parse_size(text: str) -> tuple[int, int]:
    try:
        r, lap = text.lower().split("x")
        return int(r), int(lap)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a size is ROBOTSxLAPTOPS (2x4), not {text!r}") from None


def _ms(v: float | None) -> str:
    return "-" if v is None else f"{v * 1e3:.0f}"


def rows(runs: list[LabRun]) -> list[list[str]]:
    """The table: one row per run; the busiest robot uplink against the first 1-laptop run
    of the same front-end, when there is one."""
    base: dict[str, float] = {}
    for r in runs:
        if r.laptops == 1 and r.mode not in base:
            base[r.mode] = r.uplink_bytes_s
    out = []
    for r in runs:
        s: dict[str, Any] = r.sensors
        num = {k: s.get(k, {}) for k in ("imu", "adc")}
        got = sum(v.get("samples", 0) for v in num.values())
        want = r.expected("imu") + r.expected("adc")
        lost = sum(v.get("lost", 0) for v in num.values())
        dup = sum(v.get("duplicates", 0) for v in num.values())
        p50s = sorted(x for v in num.values() for x in v.get("p50s", []))
        p50 = p50s[len(p50s) // 2] if p50s else None
        p99s = [v["p99"] for v in num.values() if v.get("p99") is not None]
        cam = s.get("camera", {})
        b = base.get(r.mode)
        ratio = f"{r.uplink_bytes_s / b:.2f}" if b else "-"
        router = f"{r.router_cores:.2f}" if r.mode == "zenoh" else "-"
        if r.bridge_cores:
            router += f" (bridges {max(r.bridge_cores):.2f})"
        out.append([
            r.mode, f"{r.robots}x{r.laptops}", f"{r.uplink_mbit_s:.1f}", ratio,
            str(sum(r.uplink_drops)), f"{got / want:.3f}" if want else "-", f"{lost}/{dup}",
            _ms(p50), _ms(max(p99s) if p99s else None),
            f"{cam.get('samples', 0) / r.expected('camera'):.2f}",
            _ms(cam.get("p99")), f"{max(r.hub_cores):.2f}", router,
            f"{sum(r.laptop_cores):.2f}",
            str(len(r.errors)),
        ])  # fmt: skip
    return out


HEADER = ["front-end", "robots x laptops", "uplink Mbit/s (max robot)", "x 1 laptop",
          "tbf drops", "IMU+ADC delivered", "lost/dup", "p50 ms", "p99 ms",
          "camera frames delivered", "camera p99 ms", "hub cores (max)", "router cores",
          "laptops' cores (sum)", "errors"]  # fmt: skip


def markdown(runs: list[LabRun]) -> str:
    lines = ["| " + " | ".join(HEADER) + " |", "|" + "---|" * len(HEADER)]
    lines += ["| " + " | ".join(row) + " |" for row in rows(runs)]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m robocli.bench.lab", description=__doc__)
    ap.add_argument("--sizes", default="1x1,2x2,2x4", help="ROBOTSxLAPTOPS,... in order")
    ap.add_argument("--modes", default="", help="front-ends: tcp, zenoh (default: both)")
    ap.add_argument("--seconds", type=float, default=10.0, help="counting window per run")
    ap.add_argument("--uplink", type=float, default=20.0, help="robot uplink, Mbit/s (0: none)")
    ap.add_argument("--poll", type=int, default=25, help="ros4mat pulls per second and sensor")
    ap.add_argument("--camera", choices=["spread", "one"], default="spread",
                    help="spread: laptop j watches robot j %% R; one: robot 0")  # fmt: skip
    ap.add_argument("--pioneer", type=int, default=0, metavar="LAPTOPS",
                    help="also: LAPTOPS watch a Pioneer that one drives, then the driver is "
                    "killed (robocli-robots[zenoh])")  # fmt: skip
    ap.add_argument("--bridge", action="store_true",
                    help="each robot also runs a simulated Pioneer and its bridge")  # fmt: skip
    ap.add_argument("--faults", action="store_true",
                    help="also: kill the Zenoh router mid-run, then a hub")  # fmt: skip
    ap.add_argument("--json", metavar="FILE", help="write every run's figures here")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing --json FILE")
    ap.add_argument("--skip-ok", action="store_true", help="exit 0 where no lab can be made")
    a = ap.parse_args(argv)
    if a.json:
        from robocli.output import check_output

        try:
            check_output(a.json, a.overwrite)  # before the lab runs, not after
        except RobocliError as exc:
            ap.error(str(exc))
    sizes = [parse_size(t) for t in a.sizes.split(",") if t]
    modes = [m for m in a.modes.split(",") if m]
    if not modes:
        modes = list(MODES)
        why = zenoh_missing()
        if why is not None:
            modes.remove("zenoh")
            print(f"lab: zenoh front-end skipped: {why}", file=sys.stderr)
    bad = [m for m in modes if m not in MODES]
    if bad:
        ap.error(f"unknown front-end {bad[0]!r}; choose from {', '.join(MODES)}")
    reason = unavailable_reason()
    if reason is not None:
        print(f"lab skipped: {reason}", file=sys.stderr)
        return 0 if a.skip_ok else 1
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # teardown on SIGTERM too
    runs: list[LabRun] = []
    phase = ""  # what a LabError is about, in its message
    try:
        try:
            for robots, laptops in sizes:
                for mode in modes:
                    print(f"lab: {mode} {robots}x{laptops} ...", file=sys.stderr, flush=True)
                    opts = {"uplink_mbit": a.uplink or None, "poll": a.poll, "camera": a.camera,
                            "bridge": a.bridge}  # fmt: skip
                    run = run_lab(mode, robots, laptops, seconds=a.seconds, **opts)
                    runs.append(run)
        finally:
            if runs:
                print(markdown(runs))
                if a.json:
                    from robocli.output import replace_output

                    with replace_output(a.json, a.overwrite, text=True) as f:
                        json.dump([r.as_dict() for r in runs], f, indent=1)
        if a.pioneer:
            from robocli.bench.lab.pioneer import class_drives_pioneer

            phase = "pioneer: "
            p = class_drives_pioneer(a.pioneer, uplink_mbit=a.uplink or None)
            delays = ", ".join(f"{d:.2f}" for d in p.stop_delays)
            print(
                f"\npioneer: {p.watchers_moving} of {a.pioneer - 1} watchers saw it move; "
                f"driver killed: stopped after {delays} s (silence {p.silence} s)"
            )
        if a.faults:
            from robocli.bench.lab.faults import fault_run

            phase = "faults: "
            fr = fault_run(uplink_mbit=a.uplink or None)
            print(f"\nfaults: router down {fr.down_s:g} s: ADC silent {fr.gap_s:.2f} s, back "
                  f"{fr.back_s:.2f} s after the restart, {fr.lost} samples never came; a hub "
                  f"killed: left (liveliness) after {fr.left_s or 0:.3f} s")  # fmt: skip
    except KeyboardInterrupt:
        print("lab: interrupted", file=sys.stderr)
        return 130
    except LabError as exc:
        print(f"lab: {phase}{exc}", file=sys.stderr)
        return 1
    for r in runs:
        for e in r.errors[:5]:
            print(f"{r.mode} {r.robots}x{r.laptops}: {e}", file=sys.stderr)
    targets = (f"targets: uplink <= {TARGET_UPLINK_RATIO} x 1 laptop, 0 lost/dup, "
               f"p99 <= {TARGET_P99_S * 1e3:.0f} ms, hub <= {TARGET_HUB_CORES} core")  # fmt: skip
    print(targets, file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
