"""Train the MLP initial-velocity field of examples/inverse/velocity_field.toml with optax's
L-BFGS through loam's JAX layer, and print the field's relative L2 error against the truth.

    python python/examples/train_velocity_field.py [iterations]

`loam invert examples/inverse/velocity_field.toml` runs the same 60 iterations with loam's
own L-BFGS; this script lets JAX and optax drive the network's 1,981 weights instead, loam
giving L and dL/dθ by its adjoint at each call.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Tuple

import jax
import jax.numpy as jnp
import numpy as np
import optax  # type: ignore[import-untyped]

import loam
from loam.jax import loss_function

jax.config.update("jax_enable_x64", True)  # type: ignore[no-untyped-call]

REPO = Path(__file__).resolve().parents[2]


class Counted:
    """A study whose gradient evaluations are counted (each is one forward run of loam and
    its adjoint)."""

    def __init__(self, study: loam.Study) -> None:
        self.study = study
        self.initial = study.initial
        self.calls = 0

    def gradient(self, theta: np.ndarray) -> Tuple[float, np.ndarray]:
        self.calls += 1
        return self.study.gradient(theta)


def main(iterations: int = 60) -> None:
    study = loam.Study(REPO / "examples" / "inverse" / "velocity_field.toml")
    counted = Counted(study)
    f = loss_function(counted)  # type: ignore[arg-type]
    theta = jnp.asarray(study.initial)
    optimiser = optax.lbfgs()
    state = optimiser.init(theta)
    value_and_grad = optax.value_and_grad_from_state(f)

    # One compiled step: the optimiser's update and its line search run as one XLA program
    # that calls loam (through the layer's callback) for each L and dL/dθ it needs.
    @jax.jit
    def step(
        theta: jax.Array, state: optax.OptState
    ) -> Tuple[jax.Array, optax.OptState, jax.Array]:
        value, grad = value_and_grad(theta, state=state)
        updates, state = optimiser.update(
            grad, state, theta, value=value, grad=grad, value_fn=f
        )
        return optax.apply_updates(theta, updates), state, value

    first = 100 * study.field_errors(np.asarray(theta))[0]
    start = time.perf_counter()
    print(f"start: field error {first:.2f} %")
    for k in range(1, iterations + 1):
        theta, state, value = step(theta, state)
        if k % 10 == 0 or k == iterations:
            error = study.field_errors(np.asarray(theta))[0]
            print(f"iteration {k:3d}: L = {float(value):.6e}, field error {100 * error:.2f} %")
    wall = time.perf_counter() - start
    print(
        f"{iterations} iterations in {wall:.1f} s ({wall / iterations:.2f} s per iteration, "
        f"{counted.calls} evaluations of L and dL/dθ)"
    )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 60)
