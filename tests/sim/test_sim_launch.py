"""robocli.sim.launch as a script calls it: the simulators the CLI starts, reached by the
clients over loopback."""

from __future__ import annotations

import pytest

from robocli import Arm, Pioneer
from robocli.errors import InvalidArgument
from robocli.sim.launch import abb_controller, pioneers


def test_pioneers_serve_on_consecutive_ports_without_a_laser() -> None:
    sims = pioneers(2, port=0, laser=False, subtype="p3at", sip_ms=50.0)
    try:
        assert len({sim.url for sim in sims}) == 2
        with Pioneer.connect(sims[1].url) as robot:
            assert robot.params.subtype == "p3at"
    finally:
        for sim in sims:
            sim.close()


def test_abb_controller_with_the_paper_model_serves_states_every_20_ms() -> None:
    with abb_controller(paper=True) as sim:
        assert sim.state_ms == 20.0 and not sim.ctl_model.exact
        motion, state = sim.serve_tcp("127.0.0.1", 0, 0)
        with Arm.connect(f"tcp://127.0.0.1?motion={motion.rsplit(':', 1)[1]}"
                         f"&state={state.rsplit(':', 1)[1]}") as arm:  # fmt: skip
            assert arm.wait_for_state() is not None
    with pytest.raises(InvalidArgument):
        abb_controller(profile="fanuc")
