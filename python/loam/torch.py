"""loam as a differentiable PyTorch function of an inversion file's unknowns.

``loss(study, theta)`` returns ``L(θ)``, the file's loss, as a 0-d tensor whose ``backward``
uses loam's discrete adjoint: the forward pass runs loam's forward model and its adjoint once
and keeps ``dL/dθ``; the backward pass returns ``grad_output · dL/dθ``.

``observe(study, theta)`` returns ``y(θ)``, the observed quantities themselves
(``study.observations()`` says which), so that the loss can be written in PyTorch; its
backward runs loam's adjoint seeded with ``grad_output`` (``Study.vjp``).

θ is a float64 CPU tensor (a float32 tensor is computed in float64 and the result cast
back).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from . import Study

__all__ = ["Loss", "Observe", "loss", "observe"]


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


class Observe(torch.autograd.Function):
    """``y(θ)``, the observed quantities of an inversion (:class:`loam.Study`), with loam's
    adjoint seeded with the cotangent of ``y`` as its backward."""

    @staticmethod
    def forward(ctx: Any, theta: torch.Tensor, study: Study) -> torch.Tensor:
        values = theta.detach().cpu().numpy().astype(np.float64)
        ctx.study = study
        ctx.theta = values
        return torch.from_numpy(study.observe(values)).to(theta.dtype)

    @staticmethod
    def backward(ctx: Any, grad_output: torch.Tensor) -> tuple[torch.Tensor, None]:
        cotangent = grad_output.detach().cpu().numpy().astype(np.float64)
        bar = ctx.study.vjp(ctx.theta, cotangent)
        return torch.from_numpy(bar).to(grad_output.dtype), None


def observe(study: Study, theta: torch.Tensor) -> torch.Tensor:
    """``y(θ)`` of ``study`` at ``theta`` (in the order of ``study.observations()``),
    differentiable by loam's adjoint."""
    value: torch.Tensor = Observe.apply(theta, study)
    return value
