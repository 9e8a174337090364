"""`loam.invert` against `loam invert`: the same optimiser, iterates and files."""

from __future__ import annotations

import _thread
import json
import subprocess
import threading
from pathlib import Path
from typing import Optional

import numpy as np
import pytest

import loam
from conftest import REPO

FRICTION = REPO / "examples" / "inverse" / "friction.toml"


def friction_file(tmp: Path, iterations: int) -> Path:
    """`examples/inverse/friction.toml` stopped after ``iterations`` iterations, written in
    ``tmp`` with its scene's path made absolute."""
    text = FRICTION.read_text()
    scene = str(REPO / "examples" / "inverse" / "dambreak_small.toml")
    text = text.replace('scene = "dambreak_small.toml"', f"scene = {json.dumps(scene)}")
    text = text.replace("max_iterations = 40", f"max_iterations = {iterations}")
    path = tmp / "friction.toml"
    path.write_text(text)
    return path


def test_invert_takes_the_iterates_of_loam_invert_to_the_last_bit(
    tmp_path: Path, loam_binary: Optional[Path]
) -> None:
    """The package and the program run the same optimiser on the same adjoint: every
    iteration's loss, parameters and gradient agree exactly (history.json keeps every digit),
    and the loss falls at every iteration."""
    if loam_binary is None:
        pytest.skip("no loam program built (cargo build --release -p loam-cli)")
    path = friction_file(tmp_path, 4)
    subprocess.run(
        [str(loam_binary), "invert", str(path), "--out", str(tmp_path / "cli")],
        check=True,
        capture_output=True,
    )
    cli = json.loads((tmp_path / "cli" / "history.json").read_text())
    py = loam.invert(path, out=tmp_path / "py")
    assert py["dir"] == str(tmp_path / "py")
    assert py["names"] == cli["names"] == ["friction[0]", "friction[1]", "friction[2]"]
    assert len(py["entries"]) == len(cli["entries"]) == 5
    for a, b in zip(py["entries"], cli["entries"]):
        assert a["loss"] == b["loss"]
        assert a["parameters"] == b["parameters"]
        assert a["gradient"] == b["gradient"]
    # The line search accepts only steps that decrease the loss.
    losses = [e["loss"] for e in py["entries"]]
    assert all(b < a for a, b in zip(losses, losses[1:]))
    for name in ("history.csv", "checkpoint.json", "history_loss.png"):
        assert (tmp_path / "py" / name).is_file()


def test_invert_resumes_to_the_iterates_of_an_uninterrupted_run(tmp_path: Path) -> None:
    """Two iterations, then `resume=True` with the stop raised to four: the same iterates as
    four in one go (the checkpoint holds the optimiser's whole state)."""
    whole = loam.invert(friction_file(tmp_path, 4), out=tmp_path / "whole")
    loam.invert(friction_file(tmp_path, 2), out=tmp_path / "parts")
    parts = loam.invert(friction_file(tmp_path, 4), out=tmp_path / "parts", resume=True)
    assert [e["parameters"] for e in parts["entries"]] == [
        e["parameters"] for e in whole["entries"]
    ]


def test_invert_refuses_a_bad_file_naming_the_field(tmp_path: Path) -> None:
    path = friction_file(tmp_path, 2)
    path.write_text(path.read_text().replace('method = "lbfgs"', 'method = "newton"'))
    with pytest.raises(loam.InversionError, match="optimizer"):
        loam.invert(path, out=tmp_path / "out")


def test_ctrl_c_stops_invert_after_an_iteration_and_keeps_the_history(tmp_path: Path) -> None:
    """A Ctrl-C during the optimisation raises KeyboardInterrupt once the iteration in
    progress has ended; the history and the checkpoint on disk hold the iterations done."""
    timer = threading.Timer(2.0, _thread.interrupt_main)
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            loam.invert(friction_file(tmp_path, 40), out=tmp_path / "out")
    finally:
        timer.cancel()
    history = json.loads((tmp_path / "out" / "history.json").read_text())
    checkpoint = json.loads((tmp_path / "out" / "checkpoint.json").read_text())
    assert 1 <= len(history["entries"]) < 41
    assert checkpoint["history"]["entries"] == history["entries"]
    assert np.isfinite(history["entries"][-1]["loss"])
