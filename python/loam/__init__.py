"""loam: a differentiable Material Point Method for geomechanics, from Python.

The package wraps the Rust library loam (distribution ``loam-mpm``):

- :class:`Scene` reads and validates a scene (a TOML or JSON file, TOML text or a dict);
  an invalid one raises :class:`SceneError` naming the field.
- :class:`Simulation` builds a scene and steps it, its particle state read as NumPy arrays.
- :func:`run` runs a scene exactly as ``loam run`` does and returns its summary.
- :func:`read_series` reads the frames a run wrote; :func:`loam.plot.plot_frame` draws a 2D
  one with matplotlib.
- :class:`Study` sets up an inversion file once and gives ``L(θ)`` and ``dL/dθ`` by loam's
  adjoint at any parameters, and the observed quantities ``y(θ)`` with their
  vector–Jacobian product ``ȳᵀ ∂y/∂θ``; :func:`gradient` is ``loam gradient``'s result as a
  dict, :func:`vjp` the product for one cotangent, and :func:`invert` runs ``loam invert``'s
  optimiser.
- :mod:`loam.jax` and :mod:`loam.torch` make a study's loss or its observed quantities a
  differentiable JAX function or PyTorch autograd function (imported on their own: they need
  JAX or PyTorch).

Units are SI (m, s, kg, Pa); stresses are Cauchy stresses, tension positive; pore
pressures are compression positive.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np

from ._loam import InversionError, SceneError, SimulationError, Scene, Simulation, Study
from . import _loam

__all__ = [
    "InversionError",
    "Scene",
    "SceneError",
    "Simulation",
    "SimulationError",
    "Study",
    "gradient",
    "invert",
    "read_series",
    "run",
    "vjp",
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


def gradient(inversion: PathLike, memory: Optional[int] = None) -> Dict[str, Any]:
    """``loam gradient``'s result for the inversion file ``inversion``, as a dict.

    Keys: ``"loss"`` (``L`` at the file's first guess), ``"names"`` (the named parameters),
    ``"theta"`` (every unknown: the named parameters, then any velocity field's weights) and
    ``"gradient"`` (``dL/dθ`` over ``theta``, float64), computed by the same code as the
    command, so equal to its ``--json`` output bit for bit. ``memory``: the bytes the explicit
    adjoint may keep (``--memory``). Raises :class:`InversionError` for an invalid file and
    :class:`SimulationError` for a run that fails.
    """
    study = Study(os.fspath(inversion), memory)
    theta = study.initial
    loss, grad = study.gradient(theta)
    return {"loss": loss, "names": study.names, "theta": theta, "gradient": grad}


def vjp(
    inversion: PathLike,
    theta: Union[np.ndarray, List[float]],
    cotangent: Union[np.ndarray, List[float]],
    memory: Optional[int] = None,
) -> np.ndarray:
    """``ȳᵀ ∂y/∂θ``: the vector–Jacobian product of the observed quantities ``y`` of the
    inversion file ``inversion`` at the unknowns ``theta`` with the cotangent ``ȳ``, by loam's
    discrete adjoint seeded with ``ȳ`` on either path (explicit or implicit; element tests by
    forward-mode duals).

    ``theta`` holds every unknown as :func:`gradient`'s ``"theta"`` does; ``cotangent`` one
    value per observed quantity, in the order of ``Study(inversion).observations()``, which
    also gives each quantity's label, data ``d`` and weight ``c``. With ``ȳ = ∂ℓ/∂y`` it is
    the gradient of any loss ``ℓ(y)``; with ``ȳ = 2c (y − d)`` it is ``loam gradient``'s.
    ``memory``: the bytes the explicit adjoint may keep (``--memory``).

    Each call sets the file up again (and reruns its ``[synthetic]`` truth run, if any): to
    evaluate many, keep a :class:`Study` and call its ``vjp``. Raises
    :class:`InversionError` for an invalid file or a ``theta`` or ``cotangent`` of the wrong
    length or with a value that is not finite, :class:`SimulationError` for a run that fails.
    """
    return Study(os.fspath(inversion), memory).vjp(theta, cotangent)


def invert(
    inversion: PathLike,
    out: Optional[PathLike] = None,
    resume: bool = False,
    memory: Optional[int] = None,
) -> Dict[str, Any]:
    """Run the optimiser of the inversion file ``inversion`` as ``loam invert`` does.

    The same code as the command, so the same iterates to the last bit and the same files:
    ``history.csv``, ``history.json``, ``checkpoint.json`` (after every iteration), the
    plots and what was recovered, in ``out``, else ``out/<file stem>``. ``resume=True``
    continues from the checkpoint in ``out`` (only the file's ``[stop]`` may have changed).
    ``memory``: the bytes the explicit adjoint may keep (``--memory``).

    Returns the parsed ``history.json`` (``"names"``, ``"truth"`` and ``"entries"``: one
    per iteration with ``"loss"``, ``"parameters"``, ``"gradient"``, ``"field_errors"``, …)
    with one more key, ``"dir"``, the output folder. Raises :class:`InversionError` for an
    invalid file (naming the field) or an output folder that cannot be written,
    :class:`SimulationError` when a run fails, and ``KeyboardInterrupt`` on Ctrl-C after the
    iteration in progress, with the history and the checkpoint kept for ``resume``.
    """
    study = Study(os.fspath(inversion), memory)
    folder = Path(study.invert(None if out is None else os.fspath(out), resume))
    history: Dict[str, Any] = json.loads((folder / "history.json").read_text())
    history["dir"] = str(folder)
    return history
