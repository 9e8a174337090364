"""The observed quantities of an inversion file and their vector–Jacobian product, from
Python and through the JAX and PyTorch layers: seeded with the file's own loss cotangent the
product is loam's gradient, and any loss written in JAX or PyTorch is differentiated by
loam's adjoint."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

import loam
from conftest import REPO, need

INVERSE = REPO / "examples" / "inverse"


@pytest.fixture(scope="module")
def friction() -> loam.Study:
    return loam.Study(INVERSE / "friction.toml")


@pytest.fixture(scope="module")
def triaxial() -> loam.Study:
    return loam.Study(INVERSE / "triaxial_mcc.toml")


def test_the_loss_cotangent_gives_the_gradient(friction: loam.Study) -> None:
    """L = Σ c (y − d)² rebuilt from the observed quantities is the file's loss, and the VJP
    with ȳ = 2c (y − d) is its gradient: the two differ only in the rounding of the seed,
    so to 1e-12 relative."""
    theta = friction.initial
    labels, data, weights = friction.observations()
    y = friction.observe(theta)
    assert y.dtype == np.float64 and y.shape == data.shape == weights.shape == (len(labels),)
    assert labels[0].startswith("step ") and "particle" in labels[0]
    loss, grad = friction.gradient(theta)
    np.testing.assert_allclose(np.sum(weights * (y - data) ** 2), loss, rtol=1e-12)
    bar = friction.vjp(theta, 2 * weights * (y - data))
    np.testing.assert_allclose(bar, grad, rtol=1e-12)


def test_the_implicit_coupled_path_from_the_top_level_function() -> None:
    """`loam.vjp` on the consolidating clay layer (implicit, coupled u–p: settlements and
    piezometers), with the loss cotangent: the gradient of `loam gradient`, to 1e-12."""
    file = INVERSE / "consolidation.toml"
    study = loam.Study(file)
    theta = study.initial
    _, data, weights = study.observations()
    y = study.observe(theta)
    bar = loam.vjp(file, theta, 2 * weights * (y - data))
    np.testing.assert_allclose(bar, loam.gradient(file)["gradient"], rtol=1e-12)


def test_a_bad_cotangent_raises_naming_it(friction: loam.Study) -> None:
    theta = friction.initial
    n = len(friction.observations()[0])
    with pytest.raises(loam.InversionError, match=rf"cotangent has 2 value\(s\); expected {n}"):
        friction.vjp(theta, np.zeros(2))
    bar = np.zeros(n)
    bar[1] = np.nan
    with pytest.raises(loam.InversionError, match=r"cotangent\[1\] = NaN"):
        friction.vjp(theta, bar)
    with pytest.raises(TypeError, match="cotangent: .*dtype float32"):
        friction.vjp(theta, np.zeros(n, dtype=np.float32))


def test_a_loss_written_in_jax_is_differentiated_by_loams_adjoint(friction: loam.Study) -> None:
    """Through `observe_function`: the file's loss written in JAX has loam's gradient
    (1e-12), and another loss, Σ sin(y), has the VJP with ȳ = cos(y) (the same call, so
    equal bits); `jax.jit` of the gradient works."""
    jax = need("jax")
    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    from loam.jax import observe_function

    y_of = observe_function(friction)
    _, data, weights = friction.observations()
    theta = jnp.asarray(friction.initial)

    def loss(t: Any) -> Any:
        return jnp.sum(jnp.asarray(weights) * (y_of(t) - jnp.asarray(data)) ** 2)

    value, grad = friction.gradient(np.asarray(theta))
    jvalue, jgrad = jax.jit(jax.value_and_grad(loss))(theta)
    np.testing.assert_allclose(float(jvalue), value, rtol=1e-12)
    np.testing.assert_allclose(jgrad, grad, rtol=1e-12)

    y = friction.observe(np.asarray(theta))
    g = jax.jit(jax.grad(lambda t: jnp.sum(jnp.sin(y_of(t)))))(theta)
    np.testing.assert_array_equal(g, friction.vjp(np.asarray(theta), np.cos(y)))


def test_torch_gradcheck_of_the_observations(triaxial: loam.Study) -> None:
    """`torch.autograd.gradcheck` of y(θ) of the Modified Cam-Clay triaxial tests (λ, κ, M)
    in float64: every column of the VJP against central differences of step eps = 1e-6 of
    the parameters, scaled to O(1) so that one step suits all three. The tolerances hold the
    differences' truncation and round-off at that step."""
    torch = need("torch")
    from loam.torch import observe

    scale = torch.tensor(triaxial.initial, dtype=torch.float64)
    z = torch.ones(len(scale), dtype=torch.float64, requires_grad=True)
    # Stresses in Pa are O(1e5): the outputs scaled to O(1) so one atol fits them all.
    _, data, _ = triaxial.observations()
    size = torch.tensor(np.maximum(np.abs(data), 1e-3), dtype=torch.float64)
    assert torch.autograd.gradcheck(
        lambda t: observe(triaxial, t * scale) / size, (z,), eps=1e-6, atol=1e-6, rtol=1e-5
    )
