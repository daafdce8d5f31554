"""srug.torch: the shadow test inside PyTorch autograd. Its gradients are srug's own backward
(checked against central differences here as test_srug.py checks srug's), and a few steps of
torch.optim.Adam on srug's visibility move occluders to cast a target shadow."""

import numpy as np
import pytest

import srug

torch = pytest.importorskip("torch", reason="srug.torch needs torch (pip install 'srug[torch]')")
import srug.torch as st  # noqa: E402


def tensors(p, logits):
    f = lambda a: torch.tensor(np.asarray(a), dtype=torch.float32, requires_grad=True)  # noqa: E731
    return f(p["means"]), f(p["log_scales"]), f(p["quats"]), f(logits)


def test_autograd_gradients_are_srugs_and_match_finite_differences(dev, shadow_problem):
    p = shadow_problem
    n, g0 = len(p["means"]), p["ground"]
    logits = np.full(n, 3.0)
    means, log_scales, rotations, opacity = tensors(p, logits)
    kw = dict(p["kw"])
    sun = kw.pop("sun")
    v = st.shadow_visibility(dev, means, log_scales, rotations, opacity, p["cam"], sun, **kw)
    assert v.shape == (96, 128) and v.dtype == torch.float32 and v.requires_grad
    weights = torch.tensor(p["weights"], dtype=torch.float32)
    (v * weights).sum().backward()
    # The same numbers as srug's own backward.
    scene = srug.Scene.from_arrays(p["means"], p["quats"], p["log_scales"], logits, sh=p["sh"], activated=False)
    direct = dev.shadow(scene, p["cam"], tile=8, **p["kw"])  # shadow_visibility's default tile
    assert np.array_equal(v.detach().numpy(), direct.visibility)
    g = direct.backward(p["weights"])
    for name, t in [("means", means), ("log_scales", log_scales), ("rotations", rotations), ("opacity_logits", opacity)]:
        assert t.grad is not None and np.allclose(t.grad.numpy(), g[name], rtol=1e-6, atol=1e-9), name

    def loss(m, o):
        with torch.no_grad():
            t = [torch.tensor(x, dtype=torch.float32) for x in (m, p["log_scales"], p["quats"], o)]
            return float((st.shadow_visibility(dev, *t, p["cam"], sun, **kw).double() * weights.double()).sum())

    # Central differences for the occluder mean, receiver height and occluder opacity with the
    # largest gradients: within 10%, as test_srug.py holds srug's backward.
    occluder = g0 + int(np.argmax(np.abs(means.grad[g0:, 0].numpy())))
    receiver = int(np.argmax(np.abs(means.grad[:g0, 2].numpy())))
    opaque = g0 + int(np.argmax(np.abs(opacity.grad[g0:].numpy())))
    # As in test_srug.py: the receiver's surface depth needs a step under its thickness.
    for i, j, h in [(occluder, 0, 0.02), (receiver, 2, 0.001), (opaque, None, 0.05)]:
        m_up, m_down, o_up, o_down = (p["means"].copy(), p["means"].copy(), logits.copy(), logits.copy())
        if j is None:
            o_up[i] += h
            o_down[i] -= h
            analytic = float(opacity.grad[i])
        else:
            m_up[i, j] += h
            m_down[i, j] -= h
            analytic = float(means.grad[i, j])
        fd = (loss(m_up, o_up) - loss(m_down, o_down)) / (2 * h)
        assert abs(fd - analytic) <= 0.1 * abs(analytic), (i, j, fd, analytic)


def test_adam_on_srugs_visibility_moves_occluders_to_a_target_shadow(dev, shadow_problem):
    """The target: the shadow of the occluders shifted 0.6 m along x. Only the occluders' means
    and opacities are trained (a torch.optim.Adam loop on BCE(V, target)); the loss falls and
    the shadowed pixels' IoU with the target rises."""
    p = shadow_problem
    n, g0 = len(p["means"]), p["ground"]
    logits = np.full(n, 3.0)
    kw = dict(p["kw"])
    sun = kw.pop("sun")
    shifted = p["means"].copy()
    shifted[g0:, 0] += 0.6
    with torch.no_grad():
        target = st.shadow_visibility(dev, *tensors({**p, "means": shifted}, logits), p["cam"], sun, **kw)
    means, log_scales, rotations, opacity = tensors(p, logits)
    optimiser = torch.optim.Adam([means, opacity], lr=0.05)
    free = torch.zeros(n, 1)
    free[g0:] = 1.0

    def iou(v):
        a, b = v < 0.5, target < 0.5
        return float((a & b).sum()) / max(1, float((a | b).sum()))

    losses, ious = [], []
    for _ in range(15):
        optimiser.zero_grad()
        v = st.shadow_visibility(dev, means, log_scales, rotations, opacity, p["cam"], sun, **kw)
        loss = torch.nn.functional.binary_cross_entropy(v.clamp(1e-6, 1 - 1e-6), target)
        loss.backward()
        means.grad *= free  # the ground stays
        opacity.grad *= free[:, 0]
        optimiser.step()
        losses.append(float(loss.detach()))
        ious.append(iou(v.detach()))
    print(f"BCE {losses[0]:.4f} -> {losses[-1]:.4f}, shadow IoU {ious[0]:.3f} -> {ious[-1]:.3f}")
    assert losses[-1] < 0.6 * losses[0] and ious[-1] > ious[0] + 0.1, (losses, ious)
    moved = (means.detach()[g0:, 0] - torch.tensor(p["means"][g0:, 0], dtype=torch.float32)).mean()
    assert 0.2 < float(moved) < 1.0, float(moved)
