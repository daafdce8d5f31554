"""srug's differentiable sun shadows inside PyTorch autograd.

``shadow_visibility`` returns the sigmoid shadow test's visibility V (H, W) of
one camera as a tensor that autograd differentiates with respect to the
Gaussians' means, log-scales, rotations (w, x, y, z) and opacity logits, so a
PyTorch 3DGS trainer can add the paper's shadow losses to its own::

    import torch, srug, srug.torch as st
    dev = srug.Device()
    v = st.shadow_visibility(dev, means, log_scales, quats, opacity_logits, cams[0], sun=(260.0, 50.0))
    loss = torch.nn.functional.binary_cross_entropy(v, target)   # target: 1 - shadow mask
    loss.backward()                                              # means.grad, ... filled

Forward and backward run on srug's device (Vulkan); tensors cross as float32
numpy arrays (zero-copy for contiguous CPU tensors, a copy from any other
device, and the gradients go back to the inputs' device and dtype). torch is an
optional dependency: ``pip install "srug[torch]"``.
"""

from typing import Any, Optional, Tuple

import numpy as np
import torch

import srug

__all__ = ["ShadowFunction", "shadow_visibility"]


def _numpy(t: torch.Tensor) -> np.ndarray:
    return np.ascontiguousarray(t.detach().to("cpu", torch.float32).numpy())


class ShadowFunction(torch.autograd.Function):
    """V = srug's shadow test of the Gaussians (means, log_scales, rotations, opacity_logits);
    the backward is srug's (`ShadowTest.backward`). Use :func:`shadow_visibility`."""

    @staticmethod
    def forward(  # type: ignore[override]
        ctx: Any,
        means: torch.Tensor,
        log_scales: torch.Tensor,
        rotations: torch.Tensor,
        opacity_logits: torch.Tensor,
        device: "srug.Device",
        sh: np.ndarray,
        camera: "srug.Cameras",
        options: dict,
    ) -> torch.Tensor:
        # A scene for this step's one frame: kept in the caller's order (moving it would not repay).
        scene = srug.Scene.from_arrays(
            _numpy(means),
            _numpy(rotations),
            _numpy(log_scales),
            _numpy(opacity_logits),
            sh=sh,
            activated=False,
            order="file",
        )
        test = device.shadow(scene, camera, **options)
        ctx.test = test
        ctx.like = (means.device, means.dtype)
        return torch.from_numpy(test.visibility).to(means.device)

    @staticmethod
    def backward(ctx: Any, grad_v: torch.Tensor) -> Tuple[Optional[torch.Tensor], ...]:  # type: ignore[override]
        g = ctx.test.backward(_numpy(grad_v))
        device, dtype = ctx.like

        def back(name: str) -> torch.Tensor:
            return torch.from_numpy(g[name]).to(device=device, dtype=dtype)

        return back("means"), back("log_scales"), back("rotations"), back("opacity_logits"), None, None, None, None


def shadow_visibility(
    device: "srug.Device",
    means: torch.Tensor,
    log_scales: torch.Tensor,
    rotations: torch.Tensor,
    opacity_logits: torch.Tensor,
    camera: "srug.Cameras",
    sun: Tuple[float, float],
    *,
    sh: Any = None,
    **shadow_options: Any,
) -> torch.Tensor:
    """The sun visibility V (H, W) of ``camera`` (one camera) under ``sun`` (azimuth, elevation in
    degrees), differentiable with respect to ``means`` (N, 3), ``log_scales`` (N, 3),
    ``rotations`` (N, 4) as w, x, y, z and ``opacity_logits`` (N,) — INRIA PLY's
    parameterisation. The shadow map and the receivers are both these Gaussians: gradients
    reach occluders and receivers alike. ``sh`` (N, K, 3) only sets the scene's colour, which
    V does not depend on (default: grey). ``shadow_options`` are :meth:`srug.Device.shadow`'s
    (resolution, k, bias, map_depth, receiver_depth, slope_bias, normal_offset, fit, tile, filter,
    surface_depth, map_surface_depth); for
    gradients that reach opacities and shapes use ``map_depth="expected"`` and
    ``receiver_depth="expected"``. ``tile`` defaults to 8 here, not 16: a training step runs the
    backward, which is about twice as fast at 8-pixel tiles (docs/python.md)."""
    n = means.shape[0]
    if sh is None:
        sh = np.zeros((n, 1, 3), np.float32)
    options = dict(shadow_options, sun=(float(sun[0]), float(sun[1])))
    options.setdefault("tile", 8)
    return ShadowFunction.apply(means, log_scales, rotations, opacity_logits, device, sh, camera, options)
