"""loam's gradient from Python against the CLI's, and the JAX and PyTorch layers against
loam's adjoint and central differences."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from typing import Any, Optional

import numpy as np
import pytest

import loam
from conftest import REPO, need

FRICTION = REPO / "examples" / "inverse" / "friction.toml"


@pytest.fixture(scope="module")
def friction() -> loam.Study:
    return loam.Study(FRICTION)


def test_the_gradient_equals_loam_gradient_to_the_last_bit(
    tmp_path: Path, loam_binary: Optional[Path]
) -> None:
    """The package and the CLI run the same code: the JSON of `loam gradient --json` holds
    every number to the last bit, so the two agree exactly."""
    if loam_binary is None:
        pytest.skip("no loam program built (cargo build --release -p loam-cli)")
    out = tmp_path / "gradient.json"
    subprocess.run(
        [str(loam_binary), "gradient", str(FRICTION), "--json", str(out)],
        check=True,
        capture_output=True,
    )
    cli = json.loads(out.read_text())
    py = loam.gradient(FRICTION)
    assert py["names"] == [p["name"] for p in cli["parameters"]]
    assert py["loss"] == cli["loss"]
    np.testing.assert_array_equal(py["theta"], cli["theta"])
    np.testing.assert_array_equal(py["gradient"], cli["gradient"])


def test_the_gradient_matches_central_differences(friction: loam.Study) -> None:
    """dL/dμ per floor segment against central differences of the study's own loss: with
    h = 1e-6 the truncation (h² L‴) and the round-off (ε L / h ≈ 1e-10 relative) leave
    agreement far inside 1e-5 where no particle switches between sticking and sliding."""
    theta = np.array(friction.initial)
    _, grad = friction.gradient(theta)
    h = 1e-6
    for k in range(len(theta)):
        step = np.zeros_like(theta)
        step[k] = h
        central = (friction.gradient(theta + step)[0] - friction.gradient(theta - step)[0]) / (
            2 * h
        )
        assert abs(grad[k] - central) <= 1e-5 * abs(central)


def test_bad_parameters_raise_naming_them(friction: loam.Study) -> None:
    with pytest.raises(loam.InversionError, match=r"theta has 2 value\(s\); expected 3"):
        friction.gradient(np.array([0.3, 0.1]))
    with pytest.raises(loam.InversionError, match=r"theta\[1\] = NaN"):
        friction.gradient(np.array([0.3, np.nan, 0.2]))
    with pytest.raises(TypeError, match=r"theta: .*shape \[1, 3\] and dtype float64"):
        friction.gradient(np.array([[0.3, 0.1, 0.2]]))
    with pytest.raises(TypeError, match="theta: .*dtype float32"):
        friction.gradient(np.array([0.3, 0.1, 0.2], dtype=np.float32))
    with pytest.raises(TypeError, match="theta: .*got str"):
        friction.gradient("0.3")  # type: ignore[arg-type]


def test_an_inversion_file_with_a_typo_raises_naming_the_field(tmp_path: Path) -> None:
    file = tmp_path / "typo.toml"
    scene = REPO / "examples" / "inverse" / "dambreak_small.toml"
    file.write_text(f'scene = "{scene}"\n[[parameters]]\nname = "friction[0]"\nintial = 0.5\n')
    with pytest.raises(loam.InversionError, match=r"parameters\[0\]\.intial: unknown field"):
        loam.Study(file)
    with pytest.raises(loam.InversionError, match="cannot read the inversion file"):
        loam.Study(tmp_path / "missing.toml")


def test_jax_jit_grad_of_the_layer_is_loams_adjoint(friction: loam.Study) -> None:
    jax = need("jax")
    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp

    from loam.jax import loss_function

    f = loss_function(friction)
    theta = jnp.asarray(friction.initial)
    loss, grad = friction.gradient(np.asarray(theta))
    np.testing.assert_array_equal(jax.jit(jax.grad(f))(theta), grad)
    value, g = jax.jit(jax.value_and_grad(f))(theta)
    assert float(value) == loss
    np.testing.assert_array_equal(g, grad)
    # The chain rule through JAX: d/ds L(s θ) at s = 1 is θ · dL/dθ.
    d = jax.grad(lambda s: f(s * theta))(1.0)
    np.testing.assert_allclose(d, float(theta @ grad), rtol=1e-14)
    # vmap runs the callback once per row.
    batch = jnp.stack([theta, theta * 0.9])
    values = jax.vmap(f)(batch)
    assert float(values[0]) == loss
    assert float(values[1]) == friction.gradient(np.asarray(batch[1]))[0]


def test_torch_gradcheck_of_the_layer(friction: loam.Study) -> None:
    torch = need("torch")
    from loam.torch import loss

    theta = torch.tensor(friction.initial, dtype=torch.float64, requires_grad=True)
    # gradcheck compares the adjoint with central differences of step eps; atol/rtol hold
    # the differences' truncation and round-off at eps = 1e-6 (see the central-difference
    # test above).
    assert torch.autograd.gradcheck(
        lambda t: loss(friction, t), (theta,), eps=1e-6, atol=1e-7, rtol=1e-5
    )
    value = loss(friction, theta)
    value.backward()  # type: ignore[no-untyped-call]
    _, grad = friction.gradient(theta.detach().numpy())
    np.testing.assert_array_equal(theta.grad.numpy(), grad)


def test_optax_lbfgs_through_the_jax_layer_recovers_the_friction(friction: loam.Study) -> None:
    """optax's L-BFGS, one jitted step per iteration, drives the three floor frictions of the
    synthetic dam-break through the layer, μ = softplus(z) keeping them positive (the chain
    rule through JAX). The observations come from a run at the truth (0.3, 0.1, 0.2), so the
    minimum is the truth with L = 0: after 20 iterations (from 0.798 each) L is below 1e-12
    and μ within 1e-5 of it (the iterates converge superlinearly: 1e-8 by then)."""
    jax = need("jax")
    jax.config.update("jax_enable_x64", True)
    optax = need("optax")
    import jax.numpy as jnp

    from loam.jax import loss_function

    f = loss_function(friction)

    def g(z: Any) -> Any:
        return f(jax.nn.softplus(z))

    optimiser = optax.lbfgs()
    value_and_grad = optax.value_and_grad_from_state(g)

    @jax.jit  # type: ignore[untyped-decorator]
    def step(z: Any, state: Any) -> Any:
        value, grad = value_and_grad(z, state=state)
        updates, state = optimiser.update(grad, state, z, value=value, grad=grad, value_fn=g)
        return optax.apply_updates(z, updates), state

    z = jnp.log(jnp.expm1(jnp.asarray(friction.initial)))
    state = optimiser.init(z)
    for _ in range(20):
        z, state = step(z, state)
    mu = np.asarray(jax.nn.softplus(z))
    truth = friction.truth
    assert truth is not None
    assert float(g(z)) < 1e-12
    np.testing.assert_allclose(mu, truth, rtol=1e-5)
