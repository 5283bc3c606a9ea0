"""The lab's fault run over Zenoh: the router killed mid-run and started again, then a
robot's hub killed, as laptops see them.

Two robots (hubs ``r0``, ``r1``, clients of the router in the server's namespace) and one
watching laptop (:func:`main` ``watch``: it prints a JSON line per ADC batch it receives and
per liveliness change, with its receive time on the host's one clock). The run kills the
router (SIGKILL), starts it again on the same endpoint after ``down_s`` seconds, and reads
the gap in the laptop's batches and the samples that never came (sequence numbers); then it
kills hub ``r1`` and reads when its liveliness token left.

``python -m robocli.bench.lab.faults watch CONFIG HUB,...`` is the laptop side.
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass
from typing import Any

from robocli.bench.lab.bench import (
    HUB_READY,
    ZENOH_PUBLISH,
    client_config,
    start_router,
)
from robocli.bench.lab.netns import Lab, wait_for

START_S = 60.0


@dataclass
class FaultRun:
    """What the laptop saw. ``gap_s``: the longest silence of hub r0's ADC around the
    router's absence; ``lost``: its samples that never came (sequence numbers); ``back_s``:
    from the router's restart to the next batch; ``left_s``: from killing hub r1 to its
    liveliness token's deletion at the laptop."""

    down_s: float
    gap_s: float = 0.0
    back_s: float = 0.0
    lost: int = 0
    left_s: float | None = None

    def as_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


def fault_run(down_s: float = 2.0, *, uplink_mbit: float | None = 20.0) -> FaultRun:
    """Run the faults (see the module) and return what the laptop saw."""
    result = FaultRun(down_s)
    py = sys.executable
    with Lab(2, 1, uplink_mbit=uplink_mbit) as lab:
        assert lab.logdir is not None
        router_proc, router = start_router(lab)
        config = client_config(lab.logdir / "client.json5", router)
        hubs = []
        for i in range(2):
            argv = [py, "-m", "robocli", "serve", "--sim", "--zenoh", str(config), "--name",
                    f"r{i}", "--publish", ZENOH_PUBLISH, "--no-tcp"]  # fmt: skip
            hubs.append(lab.spawn(lab.robot(i), argv, f"hub{i}"))
        for h in hubs:
            wait_for(lambda h=h: HUB_READY["zenoh"] in h.tail(), START_S, h.name, [h])
        watch = lab.spawn(lab.laptop(0), [py, "-m", "robocli.bench.lab.faults", "watch",
                                          str(config), "r0,r1"], "watcher")  # fmt: skip

        def batches(hub: str, after: float = 0.0) -> list[dict[str, Any]]:
            return [
                x for x in watch.json_lines(1_000_000) if x.get("hub") == hub and x["t"] > after
            ]

        wait_for(lambda: len(batches("r0")) > 20, START_S, "batches", [watch, router_proc])
        lab.stop(router_proc, sig_first=False)  # SIGKILL: no goodbye
        time.sleep(down_s)
        restarted = time.time()
        router_proc, _ = start_router(lab)
        wait_for(lambda: len(batches("r0", restarted)) > 20, START_S, "batches again",
                 [watch, router_proc])  # fmt: skip
        seen = batches("r0")
        times = [x["t"] for x in seen]
        result.gap_s = max(b - a for a, b in zip(times, times[1:], strict=False))
        result.back_s = min(t for t in times if t > restarted) - restarted
        result.lost = sum(max(0, b["first"] - (a["first"] + a["count"]))
                          for a, b in zip(seen, seen[1:], strict=False))  # fmt: skip
        gone = time.time()
        lab.stop(hubs[1], sig_first=False)

        def left() -> float | None:
            return next((x["t"] for x in watch.json_lines(1_000_000) if x.get("left") == "r1"
                         and x["t"] > gone), None)  # fmt: skip

        wait_for(lambda: left() is not None, START_S, "hub r1 leaving", [watch])
        result.left_s = float(left() or 0.0) - gone
    return result


def main(argv: list[str] | None = None) -> int:
    from robocli.bench.lab.laptop import BATCH
    from robocli.zenoh.keys import ALIVE_ALL, topic_key
    from robocli.zenoh.session import open_session

    args = sys.argv[1:] if argv is None else argv
    if len(args) != 3 or args[0] != "watch":
        print("usage: python -m robocli.bench.lab.faults watch CONFIG HUB,...", file=sys.stderr)
        return 2
    session = open_session(args[1], "client")

    def on_batch(hub: str) -> Any:
        def cb(sample: Any) -> None:
            t = time.time()
            head = BATCH.unpack_from(sample.payload.to_bytes(), 0)
            print(json.dumps({"hub": hub, "t": t, "first": head[4], "count": head[5]}),
                  flush=True)  # fmt: skip

        return cb

    def on_alive(sample: Any) -> None:
        name = str(sample.key_expr).split("/")[1]
        what = "left" if "DELETE" in str(sample.kind) else "up"
        print(json.dumps({what: name, "t": time.time()}), flush=True)

    keep = [session.liveliness().declare_subscriber(ALIVE_ALL, on_alive)]
    keep += [session.declare_subscriber(topic_key(h, "adc"), on_batch(h))
             for h in args[2].split(",")]  # fmt: skip
    print("watching", flush=True)
    while keep:  # until the bench stops us
        time.sleep(3600)
    return 0


if __name__ == "__main__":
    sys.exit(main())
