"""loam as a differentiable PyTorch function: the loss of an inversion file of its unknowns.

``loss(study, theta)`` returns ``L(θ)`` as a 0-d tensor whose ``backward`` uses loam's
discrete adjoint: the forward pass runs loam's forward model and its adjoint once and keeps
``dL/dθ``; the backward pass returns ``grad_output · dL/dθ``. θ is a float64 CPU tensor (a
float32 tensor is computed in float64 and the result cast back).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from . import Study

__all__ = ["Loss", "loss"]


class Loss(torch.autograd.Function):
    """``L(θ)`` of an inversion (:class:`loam.Study`) with loam's adjoint as its backward."""

    @staticmethod
    def forward(ctx: Any, theta: torch.Tensor, study: Study) -> torch.Tensor:
        value, grad = study.gradient(theta.detach().cpu().numpy().astype(np.float64))
        ctx.save_for_backward(torch.from_numpy(np.asarray(grad)).to(theta.dtype))
        return torch.tensor(value, dtype=theta.dtype)

    @staticmethod
    def backward(ctx: Any, grad_output: torch.Tensor) -> tuple[torch.Tensor, None]:
        (grad,) = ctx.saved_tensors
        return grad_output * grad, None


def loss(study: Study, theta: torch.Tensor) -> torch.Tensor:
    """``L(θ)`` of ``study`` at ``theta``, differentiable by loam's adjoint."""
    value: torch.Tensor = Loss.apply(theta, study)
    return value
