"""``make demo`` leaves what it made for the newcomer to open afterwards (it used to write
into a temporary folder it deleted): run whole, into a folder of the test's, it lists that
folder, and the recordings and figures it names are there. About 40 s: a slow test."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_the_demo_keeps_its_recordings_and_figures(tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    pytest.importorskip("mcap")
    out = tmp_path / "demo-out"
    for _ in range(2):  # a second make demo replaces what the first made
        proc = subprocess.run([sys.executable, str(ROOT / "examples" / "demo.py"), str(out)],
                              capture_output=True, text=True, timeout=600, cwd=tmp_path,
                              stdin=subprocess.DEVNULL)  # fmt: skip
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "what the demo made is in demo-out/ (kept):" in proc.stdout
    made = {"wander.mcap", "wander_path.png", "hub.mcap", "hub.png", "arm_circle.png",
            "sim.json", "real.json"}  # fmt: skip
    assert made <= {p.name for p in out.iterdir()}
    for name in made:
        assert f"  demo-out/{name}" in proc.stdout
    assert not (tmp_path / "arm_circle.png").exists()  # nothing left beside it
