"""Rendering a camera list across a Ray cluster.

Each Ray worker process opens its own :class:`srug.Device` and loads the scene
once (kept for the worker's later tasks); the cameras are split into chunks, one
Ray task each, and the results come back stacked in camera order, identical to
a single-process :meth:`srug.Device.render` or :meth:`srug.Device.relight`.
A task whose worker dies is retried on another worker (Ray's task retries,
``max_retries``), so a killed worker loses nothing.

Scenes and cameras travel as file paths that every worker can read (a shared
filesystem, or the same files on every node): the workers read them
themselves, so no scene crosses the object store::

    import ray, srug.distributed
    ray.init()                                   # or ray.init(address="auto") on a cluster
    out = srug.distributed.render("city.ply", "cameras.json", channels=["rgb", "depth"])
    img = srug.distributed.relight("city.ply", "cameras.json", sun=(260.0, 50.0))

Needs ``ray`` (``pip install ray``); docs/python.md has the numbers.
"""

from __future__ import annotations

import os
import signal
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

import srug

# Per worker process: (device choice, scene path, cameras path) -> (Device, Scene, Cameras).
_STATE: Dict[tuple, tuple] = {}


def _state(device: Optional[str], scene: str, cameras: str, size: Optional[Sequence[int]]):
    key = (device, scene, cameras, None if size is None else tuple(size))
    if key not in _STATE:
        dev = srug.Device(device)
        cams = srug.Cameras.from_file(cameras)
        if size is not None:
            cams = cams.resized(int(size[0]), int(size[1]))
        _STATE[key] = (dev, dev.load_scene(scene), cams)
    return _STATE[key]


def _maybe_die() -> None:
    """Test hook: with SRUG_TEST_KILL_ONCE=PATH, the first task to find PATH missing
    creates it and kills its own worker process (as an out-of-memory kill would)."""
    marker = os.environ.get("SRUG_TEST_KILL_ONCE")
    if marker:
        try:
            fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            return
        os.close(fd)
        os.kill(os.getpid(), signal.SIGKILL)


def _chunk_task(kind: str, device, scene, cameras, size, indices, options):
    dev, sc, cams = _state(device, scene, cameras, size)
    _maybe_die()
    part = cams[list(indices)]
    if kind == "render":
        return dev.render(sc, part, **options)
    return {"image": dev.relight(sc, part, **options)}


def _run(kind, scene, cameras, size, chunk, device, max_retries, indices, options) -> Dict[str, np.ndarray]:
    import ray  # only here: the package works without ray

    if not ray.is_initialized():
        ray.init()
    scene, cameras = os.fspath(scene), os.fspath(cameras)
    if indices is None:
        indices = range(len(srug.Cameras.from_file(cameras)))
    indices = [int(i) for i in indices]
    if not indices:
        raise srug._invalid("no cameras to render")
    if chunk < 1:
        raise srug._invalid(f"chunk {chunk} is not a positive number of cameras")
    task = ray.remote(max_retries=max_retries, retry_exceptions=False)(_chunk_task)
    pieces = [indices[i : i + chunk] for i in range(0, len(indices), chunk)]
    refs = [task.remote(kind, device, scene, cameras, size, p, options) for p in pieces]
    parts: List[Dict[str, np.ndarray]] = ray.get(refs)
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


def render(
    scene: Any,
    cameras: Any,
    *,
    channels: Sequence[str] = ("rgb",),
    indices: Optional[Sequence[int]] = None,
    size: Optional[Sequence[int]] = None,
    chunk: int = 8,
    device: Optional[str] = None,
    max_retries: int = 3,
    **options: Any,
) -> Dict[str, np.ndarray]:
    """:meth:`srug.Device.render` of the cameras file's cameras (``indices``: a subset, in
    that order; ``size``: (width, height) to resize them to) across the Ray cluster, ``chunk``
    cameras per task; returns the same dict of stacked arrays, in camera order."""
    return _run("render", scene, cameras, size, chunk, device, max_retries, indices, dict(channels=list(channels), **options))


def relight(
    scene: Any,
    cameras: Any,
    *,
    indices: Optional[Sequence[int]] = None,
    size: Optional[Sequence[int]] = None,
    chunk: int = 8,
    device: Optional[str] = None,
    max_retries: int = 3,
    **options: Any,
) -> np.ndarray:
    """:meth:`srug.Device.relight` across the Ray cluster (its keyword arguments pass through):
    (N, H, W, 3) in camera order."""
    return _run("relight", scene, cameras, size, chunk, device, max_retries, indices, options)["image"]
