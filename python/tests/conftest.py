"""Fixtures shared by the Python tests: a validated device and a small shadow problem."""

import numpy as np
import pytest

import srug


@pytest.fixture(scope="module")
def dev():
    """A device with the Khronos validation layer on; any message fails the module."""
    d = srug.Device(validation=True)
    assert d.validation
    yield d
    assert d.take_validation_messages() == []


@pytest.fixture
def shadow_problem():
    """A ground of flat Gaussians (heights varied, so no perturbed Gaussian sets the bounds the
    light camera is fitted to) under a cluster of 30 occluders, a camera looking down at it,
    per-pixel loss weights, and shadow options with expected (smooth) depths and no slope bias."""
    rng = np.random.default_rng(5)
    gx, gy = np.meshgrid(np.linspace(-4, 4, 40), np.linspace(-4, 4, 40))
    ground = np.stack([gx.ravel(), gy.ravel(), rng.uniform(0.0, 0.02, gx.size)], 1)
    occluders = rng.normal([0, 0, 2.0], [0.3, 0.3, 0.2], (30, 3))
    means = np.vstack([ground, occluders])
    n, g0 = len(means), len(ground)
    eye = np.array([0.0, -6.0, 5.0])
    f = -eye / np.linalg.norm(eye)
    r = np.cross(f, [0, 0, 1.0])
    r /= np.linalg.norm(r)
    rot = np.stack([r, np.cross(f, r), f], 1)
    view = np.eye(4)
    view[:3, :3], view[:3, 3] = rot.T, -rot.T @ eye
    return {
        "means": means,
        "ground": g0,
        "quats": np.tile([1.0, 0, 0, 0], (n, 1)),
        "log_scales": np.vstack(
            [np.tile(np.log([0.15, 0.15, 0.01]), (g0, 1)), np.tile(np.log([0.25] * 3), (n - g0, 1))]
        ),
        "sh": np.zeros((n, 1, 3)),
        "cam": srug.Cameras(view, [[80.0, 0, 64], [0, 80.0, 48], [0, 0, 1]], 128, 96),
        "weights": rng.uniform(0.5, 1.5, (96, 128)),
        # No slope bias: the backward holds the receivers' normals fixed, and with a slope
        # bias they carry V's dependence on opacities (through the blended normal).
        "kw": dict(
            sun=(200.0, 55.0), resolution=512, k=20.0, map_depth="expected", receiver_depth="expected", slope_bias=0.0
        ),
    }
