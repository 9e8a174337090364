"""Shared scenes and helpers of the tests."""

from __future__ import annotations

import importlib
import os
import tomllib
from pathlib import Path
from typing import Any, Dict, Optional

import pytest

REPO = Path(__file__).resolve().parents[2]


def dambreak(tmp: Path) -> Dict[str, Any]:
    """The friction dam break of ``examples/dambreak_friction.toml``, reduced to run in a
    second or two: cells of 0.02 m (1,500 particles), 3,000 steps of 3e-5 s to 0.09 s, three
    frames after the initial one, written to ``tmp``."""
    scene = tomllib.loads((REPO / "examples" / "dambreak_friction.toml").read_text())
    scene["grid"]["cell_size"] = 0.02
    scene["solver"]["end_time"] = 0.09
    scene["output"]["frames"] = 3
    scene["output"]["dir"] = str(tmp)
    return scene


def block(gravity: float = -9.8, end_time: float = 0.1) -> Dict[str, Any]:
    """An elastic block of 0.2 m × 0.2 m in the middle of a 1 m × 1 m grid without walls,
    under the gravity ``gravity`` (m/s²), fixed steps of 1e-4 s."""
    return {
        "grid": {"lo": [0.0, 0.0], "hi": [1.0, 1.0], "cell_size": 0.05},
        "materials": [
            {
                "name": "rubber",
                "model": "neo_hookean",
                "density": 1000.0,
                "youngs_modulus": 1.0e6,
                "poisson_ratio": 0.3,
            }
        ],
        "bodies": [
            {"material": "rubber", "shape": {"type": "box", "lo": [0.4, 0.6], "hi": [0.6, 0.8]}}
        ],
        "loads": {"gravity": [0.0, gravity]},
        "solver": {"time_step": {"type": "fixed", "dt": 1e-4}, "end_time": end_time},
    }


@pytest.fixture
def loam_binary() -> Optional[Path]:
    """The ``loam`` program built by ``cargo build --release`` (``LOAM_BIN`` or
    ``target/release/loam``), if there is one; under CI (``CI=true``), where the README's
    first test command has built it, a missing program fails the test."""
    given = os.environ.get("LOAM_BIN")
    path = Path(given) if given else REPO / "target" / "release" / "loam"
    if not path.is_file() and os.environ.get("CI") == "true":
        pytest.fail(f"no loam program at {path} (cargo build --release -p loam-cli)")
    return path if path.is_file() else None


def need(module: str) -> Any:
    """Imports an optional dependency of a test (``jax``, ``torch``): skips the test where it
    is not installed, but fails it under CI (``CI=true``), which installs them."""
    if os.environ.get("CI") == "true":
        return importlib.import_module(module)
    return pytest.importorskip(module)
