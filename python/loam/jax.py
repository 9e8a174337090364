"""loam as a differentiable JAX function of an inversion file's unknowns.

``loss_function(study)`` returns ``f(θ) = L(θ)``, the file's loss, with a
:func:`jax.custom_vjp` whose forward and backward call loam through
:func:`jax.pure_callback`: the forward pass runs loam's forward model and its discrete
adjoint once, keeps ``dL/dθ``, and the backward pass returns ``ct · dL/dθ``.

``observe_function(study)`` returns ``y(θ)``, the observed quantities themselves (tracked
positions, monitor velocities, deposit depths, settlements, pore pressures, reactions, element
test values: ``study.observations()`` says which), so that the loss can be written in JAX.
Its backward pass runs loam's adjoint seeded with the cotangent of ``y`` (``Study.vjp``).

So ``jax.grad``, ``jax.value_and_grad`` and ``jax.jit`` of either work, and an optax
optimiser can drive θ. Under :func:`jax.vmap` the callbacks run once per batch element
(``vmap_method="sequential"``).

loam computes in float64: enable JAX's 64-bit mode first
(``jax.config.update("jax_enable_x64", True)``), or the layer refuses to build.
"""

from __future__ import annotations

from typing import Callable

import jax
import jax.numpy as jnp
import numpy as np

from . import Study

__all__ = ["loss_function", "observe_function"]


def loss_function(study: Study) -> Callable[[jax.Array], jax.Array]:
    """``θ ↦ L(θ)`` of ``study`` as a JAX function with loam's adjoint as its VJP.

    ``θ`` is a float64 vector of ``len(study.initial)`` values: the named parameters in the
    file's order and physical units, then any velocity field's network weights. A θ that
    loam refuses (wrong length, a value that is not finite, a parameter out of its range)
    raises :class:`loam.InversionError` from the callback.
    """
    _require_x64()
    n = len(study.initial)
    shapes = (
        jax.ShapeDtypeStruct((), jnp.float64),  # type: ignore[no-untyped-call]
        jax.ShapeDtypeStruct((n,), jnp.float64),  # type: ignore[no-untyped-call]
    )

    def host(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        loss, grad = study.gradient(np.asarray(theta, dtype=np.float64))
        return np.asarray(loss, dtype=np.float64), np.asarray(grad, dtype=np.float64)

    def both(theta: jax.Array) -> tuple[jax.Array, jax.Array]:
        value, grad = jax.pure_callback(host, shapes, theta, vmap_method="sequential")
        return value, grad

    @jax.custom_vjp
    def loss(theta: jax.Array) -> jax.Array:
        return both(theta)[0]

    def forward(theta: jax.Array) -> tuple[jax.Array, jax.Array]:
        value, grad = both(theta)
        return value, grad

    def backward(grad: jax.Array, cotangent: jax.Array) -> tuple[jax.Array]:
        return (cotangent * grad,)

    loss.defvjp(forward, backward)
    return loss


def observe_function(study: Study) -> Callable[[jax.Array], jax.Array]:
    """``θ ↦ y(θ)``, the observed quantities of ``study``, as a JAX function whose VJP is
    loam's discrete adjoint seeded with the cotangent of ``y``.

    ``y`` is a float64 vector in the order of ``study.observations()`` (which also gives each
    quantity's label, data ``d`` and weight ``c``: the file's own loss is
    ``jnp.sum(c * (y - d) ** 2)``). The forward pass runs loam's forward model; the backward
    pass runs it again with the adjoint (``Study.vjp``). A θ or a cotangent that loam refuses
    raises :class:`loam.InversionError` from the callback.
    """
    _require_x64()
    n = len(study.initial)
    m = len(study.observations()[0])
    observed = jax.ShapeDtypeStruct((m,), jnp.float64)  # type: ignore[no-untyped-call]
    pulled = jax.ShapeDtypeStruct((n,), jnp.float64)  # type: ignore[no-untyped-call]

    def host_observe(theta: np.ndarray) -> np.ndarray:
        return study.observe(np.asarray(theta, dtype=np.float64))

    def host_vjp(theta: np.ndarray, cotangent: np.ndarray) -> np.ndarray:
        return study.vjp(
            np.asarray(theta, dtype=np.float64), np.asarray(cotangent, dtype=np.float64)
        )

    @jax.custom_vjp
    def observe(theta: jax.Array) -> jax.Array:
        y: jax.Array = jax.pure_callback(
            host_observe, observed, theta, vmap_method="sequential"
        )
        return y

    def forward(theta: jax.Array) -> tuple[jax.Array, jax.Array]:
        return observe(theta), theta

    def backward(theta: jax.Array, cotangent: jax.Array) -> tuple[jax.Array]:
        bar: jax.Array = jax.pure_callback(
            host_vjp, pulled, theta, cotangent, vmap_method="sequential"
        )
        return (bar,)

    observe.defvjp(forward, backward)
    return observe


def _require_x64() -> None:
    """Refuses to build a layer unless JAX computes in float64, as loam does."""
    if not jax.config.read("jax_enable_x64"):  # type: ignore[no-untyped-call]
        raise RuntimeError(
            "loam.jax needs JAX's 64-bit mode: call "
            'jax.config.update("jax_enable_x64", True) before building the layer'
        )
