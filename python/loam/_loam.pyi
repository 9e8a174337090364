"""Type stubs of the compiled module ``loam._loam``."""

from os import PathLike
from pathlib import Path
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, PathLike[str]]

class SceneError(ValueError):
    """A scene that cannot be read, parsed or validated, or that a run refuses.

    The message is what ``loam check`` prints for it.
    """

    path: Optional[str]
    """The field path of the first problem (e.g. ``materials[0].density``), or None."""
    issues: List[Tuple[str, str]]
    """Every problem as a (field path, message) pair."""

class SimulationError(RuntimeError):
    """A simulation step or a run that failed (the solver's message)."""

class InversionError(ValueError):
    """An invalid inversion file or parameters it refuses; the message names the field."""

class Study:
    """An inversion file set up once: ``L(θ)`` and ``dL/dθ`` by loam's adjoint."""

    def __init__(self, path: _Path, memory: Optional[int] = None) -> None:
        """Read, validate and set up the inversion file ``path``."""
    @property
    def names(self) -> List[str]:
        """The named parameters, the first unknowns."""
    @property
    def initial(self) -> npt.NDArray[np.float64]:
        """The first guess of every unknown."""
    @property
    def truth(self) -> Optional[npt.NDArray[np.float64]]:
        """The named parameters' truth values, when the file gives each one."""
    def gradient(
        self, theta: Union[npt.NDArray[np.float64], List[float]]
    ) -> Tuple[float, npt.NDArray[np.float64]]:
        """``(L, dL/dθ)`` at ``theta`` by the discrete adjoint."""
    def observations(
        self,
    ) -> Tuple[List[str], npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """The observed quantities' labels, data ``d`` and weights ``c``."""
    def observe(
        self, theta: Union[npt.NDArray[np.float64], List[float]]
    ) -> npt.NDArray[np.float64]:
        """The observed quantities ``y(θ)`` by a forward run."""
    def vjp(
        self,
        theta: Union[npt.NDArray[np.float64], List[float]],
        cotangent: Union[npt.NDArray[np.float64], List[float]],
    ) -> npt.NDArray[np.float64]:
        """``ȳᵀ ∂y/∂θ`` by the discrete adjoint seeded with ``ȳ``."""
    def field_errors(self, theta: Union[npt.NDArray[np.float64], List[float]]) -> List[float]:
        """Each velocity field's relative L2 error against the truth at ``theta``."""
    def invert(self, out: Optional[_Path] = None, resume: bool = False) -> Path:
        """Run the file's optimiser as ``loam invert`` does; returns the output folder."""

class Scene:
    """A validated scene."""

    @staticmethod
    def from_file(path: _Path) -> Scene:
        """Read and validate a scene file (``.toml`` or ``.json``)."""
    @staticmethod
    def from_toml(text: str) -> Scene:
        """Parse and validate a scene written in TOML."""
    @staticmethod
    def from_dict(scene: Dict[str, Any]) -> Scene:
        """Validate a scene given as a dict of its sections."""
    @property
    def dim(self) -> int:
        """The dimension, 2 or 3."""
    @property
    def solver(self) -> str:
        """``"explicit"`` or ``"implicit"``."""
    @property
    def source(self) -> Optional[Path]:
        """The file the scene was read from, or None."""
    @property
    def output_dir(self) -> Path:
        """The folder a run of the scene writes to."""
    def to_json(self) -> str:
        """The scene as JSON text."""
    def to_dict(self) -> Dict[str, Any]:
        """The scene as a dict of its sections."""
    def to_toml(self) -> str:
        """The scene as TOML text."""

class Simulation:
    """A scene's solver and particles, stepped from Python."""

    def __init__(self, scene: Scene, device: str = "cpu") -> None:
        """Build ``scene`` for stepping on ``device``: ``"cpu"``, or ``"gpu"`` (explicit)."""
    def step(self, n: int = 1) -> None:
        """Take ``n`` steps (explicit) or load steps (implicit)."""
    def advance_to(self, t: float) -> None:
        """Step an explicit scene to the time ``t`` (s)."""
    @property
    def time(self) -> float:
        """Simulated time (s)."""
    @property
    def steps(self) -> int:
        """Steps completed."""
    @property
    def load_factor(self) -> Optional[float]:
        """The load factor of an implicit scene, None for an explicit one."""
    @property
    def dim(self) -> int:
        """The dimension, 2 or 3."""
    @property
    def positions(self) -> npt.NDArray[np.float64]:
        """Particle positions, N × D (m); a copy."""
    @property
    def velocities(self) -> npt.NDArray[np.float64]:
        """Particle velocities, N × D (m/s); a copy."""
    @velocities.setter
    def velocities(self, value: npt.NDArray[np.float64]) -> None:
        """Set every particle's velocity from an N × D float64 array."""
    @property
    def stress(self) -> npt.NDArray[np.float64]:
        """Cauchy stress, N × 3 × 3 (Pa, tension positive); a copy."""
    @property
    def deformation_gradient(self) -> npt.NDArray[np.float64]:
        """Deformation gradient, N × D × D; a copy."""
    @property
    def pore_pressure(self) -> npt.NDArray[np.float64]:
        """Pore pressure, N (Pa, compression positive); a copy."""
    @property
    def masses(self) -> npt.NDArray[np.float64]:
        """Particle masses, N (kg; per metre of thickness in 2D); a copy."""
    @property
    def material(self) -> npt.NDArray[np.int64]:
        """Material index of every particle, N; a copy."""

def run(
    scene: Scene,
    out: Optional[_Path] = None,
    quiet: bool = True,
    device: Optional[str] = None,
) -> Path:
    """Run a scene as ``loam run`` does; returns the output folder."""

def read_series(folder: _Path) -> Tuple[List[float], List[Dict[str, npt.NDArray[Any]]]]:
    """The frame times and, per frame, its fields by name."""
