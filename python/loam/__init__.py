"""loam: a differentiable Material Point Method for geomechanics, from Python.

The package wraps the Rust library loam (distribution ``loam-mpm``):

- :class:`Scene` reads and validates a scene (a TOML or JSON file, TOML text or a dict);
  an invalid one raises :class:`SceneError` naming the field.
- :class:`Simulation` builds a scene and steps it, its particle state read as NumPy arrays.
- :func:`run` runs a scene exactly as ``loam run`` does and returns its summary.
- :func:`read_series` reads the frames a run wrote.

Units are SI (m, s, kg, Pa); stresses are Cauchy stresses, tension positive; pore
pressures are compression positive. Gradients, inversions and layers for JAX or PyTorch
are not available from Python yet.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np

from ._loam import SceneError, SimulationError, Scene, Simulation
from . import _loam

__all__ = [
    "Scene",
    "SceneError",
    "Simulation",
    "SimulationError",
    "read_series",
    "run",
]

PathLike = Union[str, "os.PathLike[str]"]


def run(
    scene: Union[Scene, PathLike],
    out: Optional[PathLike] = None,
    quiet: bool = True,
    device: Optional[str] = None,
) -> Dict[str, Any]:
    """Run a scene exactly as ``loam run`` does and return its run summary.

    ``scene`` is a :class:`Scene` or the path of a scene file. The frames
    (``particles.pvd`` and a ``.vtu`` file per frame) and ``summary.json`` go to ``out``,
    else to the scene's ``output.dir`` (``out/<file stem>``, or ``out/scene`` for a scene
    not read from a file). ``quiet=False`` shows the progress on stderr. ``device``
    (``"cpu"`` or ``"gpu"``) overrides the scene's ``solver.device``.

    Returns the parsed ``summary.json`` with one more key, ``"dir"``, the output folder.
    Raises :class:`SceneError` for a scene that is invalid or refused before the first step,
    :class:`SimulationError` when the run fails (with the run's error), and
    ``KeyboardInterrupt`` on Ctrl-C, after the run stopped cleanly at the end of its step in
    progress (its summary then says ``interrupted``).
    """
    if not isinstance(scene, Scene):
        if not isinstance(scene, (str, os.PathLike)):
            raise TypeError(
                f"scene: expected a loam.Scene or a path, got {type(scene).__name__}"
            )
        scene = Scene.from_file(os.fspath(scene))
    folder = Path(_loam.run(scene, None if out is None else os.fspath(out), quiet, device))
    summary: Dict[str, Any] = json.loads((folder / "summary.json").read_text())
    summary["dir"] = str(folder)
    return summary


def read_series(folder: PathLike) -> Tuple[np.ndarray, List[Dict[str, np.ndarray]]]:
    """Read the frames of a run's output folder.

    Returns the frame times (a float64 array, s) and, per frame, a dict of field name to
    NumPy array: ``"position"`` for the particle positions and one entry per field the run
    wrote (``velocity``, ``stress``, ``pressure``, ``material_id``, …). Vectors are N × 3
    and tensors N × 3 × 3 as the frames store them (zero-padded to 3D in a 2D run); real
    fields are float64 with the bits the run wrote, integer ones int64.
    """
    times, frames = _loam.read_series(os.fspath(folder))
    return np.asarray(times, dtype=np.float64), frames
