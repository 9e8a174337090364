"""A quick look at a 2D frame with matplotlib (``pip install "loam-mpm[plot]"``)."""

from __future__ import annotations

from typing import Any, Dict, Optional, Tuple, Union

import numpy as np
import numpy.typing as npt


def values(
    frame: Dict[str, np.ndarray],
    field: str,
    component: Union[None, int, Tuple[int, int]] = None,
) -> Tuple[npt.NDArray[np.float64], str]:
    """One number per particle of ``frame[field]`` and its label.

    A scalar field as it is; a vector's length ``|v|``, or its ``component`` ``i``; a
    tensor's mean stress ``p = −tr σ / 3`` (compression positive, as soil mechanics counts
    it), or its ``component`` ``(i, j)``. An unknown field raises ``KeyError`` naming those
    the frame has.
    """
    if field not in frame:
        raise KeyError(f"field {field!r}: the frame has {sorted(frame)}")
    a = np.asarray(frame[field], dtype=np.float64)
    if a.ndim == 1:
        return a, field
    if a.ndim == 2:
        if component is None:
            return np.linalg.norm(a, axis=1), f"|{field}|"
        if not isinstance(component, int):
            raise TypeError(f"component: a vector field takes an int, got {component!r}")
        return a[:, component], f"{field}[{component}]"
    if component is None:
        return -np.trace(a, axis1=1, axis2=2) / 3.0, f"p = −tr {field} / 3 (compression +)"
    if not isinstance(component, tuple):
        raise TypeError(f"component: a tensor field takes a pair (i, j), got {component!r}")
    i, j = component
    return a[:, i, j], f"{field}[{i}, {j}]"


def plot_frame(
    frame: Dict[str, np.ndarray],
    field: Optional[str] = None,
    component: Union[None, int, Tuple[int, int]] = None,
    ax: Optional[Any] = None,
    **scatter: Any,
) -> Any:
    """Scatter the particles of a 2D frame (one of :func:`loam.read_series`'s), coloured by
    ``field`` (see :func:`values`), with a colour bar, on ``ax`` (else the current axes).

    ``scatter`` goes to ``Axes.scatter`` (``s`` for the marker size, ``cmap``, …). Returns
    the ``PathCollection``; the axes get equal scales and labels in m.
    """
    import matplotlib.pyplot as plt

    ax = plt.gca() if ax is None else ax
    x = np.asarray(frame["position"], dtype=np.float64)
    scatter.setdefault("s", 2.0)
    scatter.setdefault("linewidths", 0.0)
    if field is None:
        points = ax.scatter(x[:, 0], x[:, 1], **scatter)
    else:
        c, label = values(frame, field, component)
        points = ax.scatter(x[:, 0], x[:, 1], c=c, **scatter)
        ax.figure.colorbar(points, ax=ax, label=label)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    return points
