"""srug: render and relight 3D Gaussian Splatting city scenes on any Vulkan device.

A native extension over srug's Rust library. Quick start::

    import srug
    dev = srug.Device()                                   # or srug.Device("cpu"), as --device
    scene = dev.load_scene("city.ply")                    # any format srug reads
    cams = srug.Cameras.from_file("cameras.json")         # cameras.json, COLMAP, transforms.json
    out = dev.render(scene, cams, channels=["rgb", "depth"])   # {"rgb": (N,H,W,3), "depth": (N,H,W), "alpha": ...}
    img = dev.relight(scene, cams, sun=(260.0, 50.0), preset="balanced")  # (N,H,W,3) linear radiance

Arrays come back as float32 numpy arrays (uint32 for ``top_gaussian``);
inputs take anything ``numpy.asarray`` takes. Every failure raises
:class:`srug.Error` with srug's message and a ``kind``. See docs/python.md.
"""

from __future__ import annotations

import os
import sys
from typing import Any, Callable, Dict, Iterable, Optional, Sequence, Tuple, Union

import numpy as np

from . import _srug
from ._srug import Error, version

__all__ = [
    "Cameras",
    "Device",
    "Error",
    "Scene",
    "ShadowTest",
    "demo_city",
    "sun_position",
    "version",
]

PathLike = Union[str, "os.PathLike[str]"]
Progress = Union[None, bool, Callable[[int, int], Any]]

# Spherical-harmonic band 0 constant: colour = SH_C0 * sh[0] + 0.5.
SH_C0 = 0.28209479177387814


def _invalid(message: str) -> Error:
    e = Error(message)
    e.kind = "invalid_argument"
    return e


def _float32(value: Any, name: str, shape: Sequence[Optional[int]]) -> np.ndarray:
    """`value` as a C-contiguous float32 array of `shape` (None: any length)."""
    try:
        a = np.asarray(value)
    except Exception as e:  # noqa: BLE001 - whatever numpy refuses, say which argument
        raise _invalid(f"{name}: cannot be read as an array ({e})") from None
    if a.dtype.kind not in "fiu":
        raise _invalid(f"{name}: dtype {a.dtype} is not numeric (float32 expected)")
    if a.ndim != len(shape) or any(w is not None and s != w for s, w in zip(a.shape, shape)):
        want = ", ".join("N" if w is None else str(w) for w in shape)
        raise _invalid(f"{name}: shape {a.shape} is not ({want})")
    return np.ascontiguousarray(a, dtype=np.float32)


def _progress(progress: Progress, total: int, what: str) -> Optional[Callable[[int, int], Any]]:
    """A (done, total) callback: the caller's, a tqdm bar or a line per 8 frames when True."""
    if progress is None or progress is False:
        return None
    if callable(progress):
        return progress
    try:
        from tqdm import tqdm  # type: ignore[import-not-found]
    except ImportError:
        tqdm = None
    if tqdm is not None and sys.stderr.isatty():
        bar = tqdm(total=total, unit=what)

        def update(done: int, n: int) -> None:
            bar.update(done - bar.n)
            if done == n:
                bar.close()

        return update

    def line(done: int, n: int) -> None:
        if done % 8 == 0 or done == n:
            print(f"srug: {done}/{n} {what}", file=sys.stderr, flush=True)

    return line


class Scene:
    """A scene of 3D Gaussians, uploaded to each :class:`Device` on first use."""

    def __init__(self, native: "_srug.Scene") -> None:
        self._native = native

    @staticmethod
    def from_file(path: PathLike, order: str = "auto") -> "Scene":
        """Reads INRIA PLY, compressed PLY, .splat, .spz, SOG or GLB (detected from the content).
        ``order``: where its Gaussians go on each device, as :meth:`Device.load_scene`'s."""
        return Scene(_srug.Scene.from_file(os.fspath(path), order))

    @staticmethod
    def from_arrays(
        means: Any,
        quats: Any,
        scales: Any,
        opacities: Any,
        sh: Any = None,
        colors: Any = None,
        activated: bool = True,
        *,
        normals: Any = None,
        albedo: Any = None,
        roughness: Any = None,
        metallic: Any = None,
        ao: Any = None,
        visibility: Any = None,
        order: str = "auto",
    ) -> "Scene":
        """A scene from arrays with gsplat's names and meanings.

        ``means`` (N, 3); ``quats`` (N, 4) as w, x, y, z; ``scales`` (N, 3) and
        ``opacities`` (N,) activated (scales > 0, opacities in [0, 1]) unless
        ``activated=False`` (log-scales and logits, as INRIA PLY stores them);
        colour as ``sh`` (N, K, 3) with K = 1, 4, 9 or 16, or as ``colors``
        (N, 3) RGB in [0, 1] (stored as the SH band 0). Relighting needs ``albedo`` (N, 3); with it
        ``roughness``, ``metallic``, ``ao``, ``visibility`` (N,) and ``normals`` (N, 3) are optional,
        activated (in [0, 1]) unless ``activated=False`` (logits, as srug's PLY stores them).
        ``order``: where the Gaussians go on each device, as :meth:`Device.load_scene`'s; ``"file"``
        for a scene made for one frame (a training step's), which the move would not repay.
        """
        m = _float32(means, "means", (None, 3))
        n = m.shape[0]
        q = _float32(quats, "quats", (n, 4))
        s = _float32(scales, "scales", (n, 3))
        o = _float32(opacities, "opacities", (n,))
        if (sh is None) == (colors is None):
            raise _invalid("give exactly one of sh (N, K, 3) and colors (N, 3)")
        if sh is None:
            c = _float32(colors, "colors", (n, 3))
            h = ((c - 0.5) / SH_C0).reshape(n, 1, 3).astype(np.float32)
        else:
            h = _float32(sh, "sh", (n, None, 3))
        def opt(value: Any, name: str, k: int) -> Optional[np.ndarray]:
            return None if value is None else _float32(value, name, (n, k) if k > 1 else (n,))

        return Scene(
            _srug.Scene.from_arrays(
                m,
                q,
                s,
                o,
                np.ascontiguousarray(h),
                activated,
                opt(normals, "normals", 3),
                opt(albedo, "albedo", 3),
                opt(roughness, "roughness", 1),
                opt(metallic, "metallic", 1),
                opt(ao, "ao", 1),
                opt(visibility, "visibility", 1),
                order,
            )
        )

    def save(self, path: PathLike, format: Optional[str] = None) -> None:
        """Writes the scene in the format its extension names (.ply, .spz, .splat, .sog, .glb),
        or ``format`` (e.g. "compressed-ply"; docs/formats.md says what each keeps)."""
        self._native.save(os.fspath(path), format)

    def arrays(self) -> Dict[str, np.ndarray]:
        """Copies of the arrays as srug stores them: means, quats (w, x, y, z), log_scales,
        opacity_logits, sh (N, K, 3); ``Scene.from_arrays(..., activated=False)`` takes them back."""
        return self._native.arrays()

    @property
    def count(self) -> int:
        """The number of Gaussians."""
        return self._native.count

    def __len__(self) -> int:
        return self._native.count

    @property
    def sh_degree(self) -> int:
        """The spherical-harmonic degree stored (0 to 3)."""
        return self._native.sh_degree

    @property
    def relightable(self) -> bool:
        """Whether the scene has the albedo attribute relighting needs."""
        return self._native.relightable

    @property
    def bounds(self) -> Optional[Tuple[Tuple[float, float, float], Tuple[float, float, float]]]:
        """((min x, y, z), (max x, y, z)) of the centres; None when empty."""
        return self._native.bounds

    def __repr__(self) -> str:
        return repr(self._native)


class Cameras:
    """Cameras: pose, intrinsics, lens and image size, one per frame.

    ``Cameras(viewmats, Ks, width, height)`` as gsplat takes them:
    ``viewmats`` (N, 4, 4) world-to-camera with OpenCV axes (x right, y down,
    z forward), ``Ks`` (N, 3, 3) pinhole intrinsics in pixels (pixel centres
    at +0.5). A single (4, 4) and (3, 3) make one camera.
    """

    def __init__(
        self,
        viewmats: Any = None,
        Ks: Any = None,  # noqa: N803 - gsplat's name
        width: Optional[int] = None,
        height: Optional[int] = None,
        near: float = 0.01,
        far: float = 1.0e4,
        names: Optional[Sequence[str]] = None,
        _native: Optional["_srug.Cameras"] = None,
    ) -> None:
        if _native is not None:
            self._native = _native
            return
        if viewmats is None or Ks is None or width is None or height is None:
            raise _invalid("Cameras needs viewmats, Ks, width and height (or Cameras.from_file)")
        v = np.asarray(viewmats)
        k = np.asarray(Ks)
        if v.ndim == 2:
            v = v[None]
        if k.ndim == 2:
            k = k[None]
        v = _float32(v, "viewmats", (None, 4, 4))
        k = _float32(k, "Ks", (v.shape[0], 3, 3))
        for name, value in (("width", width), ("height", height)):
            if not isinstance(value, (int, np.integer)) or value <= 0:
                raise _invalid(f"{name} {value!r} is not a positive integer")
        self._native = _srug.Cameras(
            v, k, int(width), int(height), float(near), float(far), None if names is None else list(names)
        )

    @staticmethod
    def from_file(path: PathLike) -> "Cameras":
        """Reads INRIA cameras.json, a COLMAP sparse model (folder or file, text or binary) or a
        nerfstudio/instant-ngp transforms.json (detected), lenses included."""
        return Cameras(_native=_srug.Cameras.from_file(os.fspath(path)))

    def resized(self, width: int, height: int) -> "Cameras":
        """The same cameras with ``width`` × ``height`` images (intrinsics scaled)."""
        return Cameras(_native=self._native.resized(int(width), int(height)))

    def panoramas(self, width: int) -> "Cameras":
        """Each camera as a 360° × 180° equirectangular panorama ``width`` × ``width // 2``."""
        return Cameras(_native=self._native.panoramas(int(width)))

    def __getitem__(self, index: Union[int, slice, Sequence[int]]) -> "Cameras":
        n = len(self)
        if isinstance(index, slice):
            indices = list(range(n))[index]
        elif isinstance(index, (int, np.integer)):
            i = int(index)
            indices = [i + n if i < 0 else i]
        else:
            indices = [int(i) for i in index]
        return Cameras(_native=self._native.select(indices))

    def __len__(self) -> int:
        return len(self._native)

    @property
    def names(self) -> list:
        """Each camera's name (its image name where the file has one)."""
        return self._native.names

    @property
    def sizes(self) -> list:
        """Each camera's (width, height)."""
        return self._native.sizes

    @property
    def lenses(self) -> list:
        """Each camera's lens, as text ("Pinhole", "Equirectangular", ...)."""
        return self._native.lenses

    @property
    def viewmats(self) -> np.ndarray:
        """(N, 4, 4) float32 world-to-camera matrices, OpenCV axes."""
        return self._native.viewmats

    @property
    def Ks(self) -> np.ndarray:  # noqa: N802 - gsplat's name
        """(N, 3, 3) float32 intrinsics (lens distortion is not in them)."""
        return self._native.ks

    def __repr__(self) -> str:
        return repr(self._native)


class Device:
    """A Vulkan device with srug's kernels.

    ``device`` as the CLI's ``--device``: an index from ``srug devices``,
    ``"gpu"``, ``"cpu"`` or part of a name (None: ``SRUG_DEVICE``, else
    automatic). ``validation`` runs the Khronos validation layer (None:
    ``SRUG_VALIDATION``). The GIL is released while the GPU works; several
    threads may render on one device at once.
    """

    def __init__(self, device: Union[None, str, int] = None, validation: Optional[bool] = None) -> None:
        self._native = _srug.Device(None if device is None else str(device), validation)

    def close(self) -> None:
        """Releases the device's kernels and working memory (the Vulkan device goes once the
        scenes uploaded to it are gone too); later calls raise :class:`srug.Error`."""
        self._native.close()

    @property
    def closed(self) -> bool:
        """Whether :meth:`close` was called."""
        return self._native.closed

    def __enter__(self) -> "Device":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    @property
    def name(self) -> str:
        """The device's name, as its driver reports it."""
        return self._native.name

    @property
    def validation(self) -> bool:
        """Whether the validation layer runs."""
        return self._native.validation

    def take_validation_messages(self) -> list:
        """The validation layer's messages since the last call (empty: none, or layer off)."""
        return self._native.take_validation_messages()

    def memory(self) -> Dict[str, int]:
        """GPU memory srug holds: ``{"current_bytes": ..., "peak_bytes": ..., "pooled_bytes": ...,
        "fresh_allocations": ...}``.

        ``pooled_bytes``: freed buffers kept (up to an eighth of the device's memory,
        256 MiB to 4 GiB, and never so much that in use and kept would pass the most
        ever in use: a new allocation frees the oldest first) for reuse by later ones of
        their kind and about their size; not counted in ``current_bytes``.
        ``fresh_allocations``: allocations since the device was made that took new
        memory rather than a kept buffer (steady frames take few or none).
        """
        return self._native.memory()

    def release_pooled_memory(self) -> int:
        """Frees the buffers kept for reuse (``memory()["pooled_bytes"]``); returns the bytes released.

        srug frees them itself when an allocation finds no memory or puts more in use
        than ever; call this to hand the memory back sooner (say, to the rest of a host
        application between bursts of work).
        """
        return self._native.release_pooled_memory()

    def last_timings(self) -> list:
        """Per camera of the last render or relight: a list of (stage, milliseconds)."""
        return self._native.last_timings()

    def load_scene(self, path: PathLike, order: str = "auto") -> Scene:
        """Reads a scene file (any format srug reads) and uploads it to this device.

        ``order``: where its Gaussians go on the device: ``"auto"`` (along a
        Morton curve when the file lists them in no spatial order, as trained
        scenes do: faster frames, the same image), ``"morton"`` or ``"file"``.
        Ids (``top_gaussian``), ``Scene.arrays`` and gradients stay in file
        order whatever the device's.
        """
        return Scene(self._native.load_scene(os.fspath(path), order))

    def render(
        self,
        scene: Scene,
        cameras: Cameras,
        channels: Iterable[str] = ("rgb",),
        background: Sequence[float] = (0.0, 0.0, 0.0),
        sh_degree: Optional[int] = None,
        tile: int = 16,
        progress: Progress = None,
        surface_depth: bool = False,
        host_depth: Optional[np.ndarray] = None,
        depth_convention: str = "camera_z",
        near: float = 0.0,
        far: float = 0.0,
        median_coverage: float = 0.5,
    ) -> Dict[str, np.ndarray]:
        """Splats every camera into G-buffer channels, stacked over the cameras.

        ``channels``: any of rgb, depth, median_depth, normal, albedo,
        roughness, metallic, ao, visibility, top_gaussian, range (also
        "materials", "all"); alpha always comes. Returns name → array:
        (N, H, W, 3) for rgb, normal and albedo, (N, H, W) for the others,
        float32, uint32 for top_gaussian (4294967295 where no Gaussian
        reaches). Blended channels other than rgb are premultiplied by alpha
        (divide depth by alpha for the expected depth). ``progress``: a
        callable (done, total), or True for a bar (tqdm) or progress lines.
        ``surface_depth``: depths where each pixel's ray meets the splat's plane
        (its shortest axis) instead of at its centre (pinhole cameras).
        ``host_depth``: your meshes' depth, (H, W) for every camera or (N, H, W),
        as camera z (``depth_convention="camera_z"``, 0 or inf: nothing),
        Vulkan [0, 1] depth (``"vulkan"``, 1: nothing) or reversed-Z
        (``"reversed_z"``, 0: nothing; ``far`` may be inf), with ``near`` and
        ``far``: splats behind it are hidden per pixel, so with a black
        background ``rgb + (1 - alpha) * yours`` composites the two.
        ``median_coverage``: the coverage 1 − T at which median_depth reads a
        pixel's depth, strictly between 0 and 1 (0.5: the median; 0 where
        coverage never gets there).
        """
        if isinstance(channels, str):
            channels = [channels]
        names = [str(c) for c in channels]
        bg = tuple(float(v) for v in background)
        if len(bg) != 3:
            raise _invalid(f"background {background!r} is not r, g, b")
        cb = _progress(progress, len(cameras), "cameras")
        return self._native.render(
            scene._native,
            cameras._native,
            names,
            bg,
            sh_degree,
            int(tile),
            cb,
            surface_depth=bool(surface_depth),
            host_depth=None if host_depth is None else np.ascontiguousarray(host_depth, dtype=np.float32),
            depth_convention=str(depth_convention),
            near=float(near),
            far=float(far),
            median_coverage=float(median_coverage),
        )

    def relight(
        self,
        scene: Scene,
        cameras: Cameras,
        sun: Optional[Tuple[float, float]] = (260.0, 50.0),
        *,
        time: Optional[str] = None,
        latitude: Optional[float] = None,
        longitude: Optional[float] = None,
        sun_intensity: float = float(np.pi),
        preset: str = "balanced",
        environment: Optional[PathLike] = None,
        env_rotation: float = 0.0,
        env_intensity: float = 1.0,
        exposure: float = 0.0,
        output: str = "radiance",
        progress: Progress = None,
        surface_depth: Optional[bool] = None,
        shadow_fit: str = "scene",
        host_depth: Optional[np.ndarray] = None,
        depth_convention: str = "camera_z",
        near: float = 0.0,
        far: float = 0.0,
        background: Optional[Tuple[float, float, float]] = None,
        return_alpha: bool = False,
        shadow_cull: bool = False,
        shadow_resolution: Optional[int] = None,
        shadow_k: Optional[float] = None,
        shadow_bias: Optional[float] = None,
        shadow_slope_bias: Optional[float] = None,
        shadow_normal_offset: Optional[float] = None,
        receiver_depth: Optional[str] = None,
        shadow_test: Optional[str] = None,
        shadow_filter: Optional[str] = None,
        shadow_cascades: Optional[int] = None,
        map_surface_depth: Optional[bool] = None,
        map_coverage: Optional[float] = None,
        receiver_coverage: Optional[float] = None,
    ) -> Any:
        """Relights every camera: (N, H, W, 3) float32.

        The sun by ``sun=(azimuth, elevation)`` in degrees (azimuth from north
        toward east; None: no sun), or by ``time`` (ISO 8601 with a zone) with
        ``latitude`` and ``longitude``. ``preset``: fast, balanced or
        reference. ``environment``: an EXR/HDR/KTX2 map or a folder from
        ``srug prefilter`` (None: the procedural sky of the sun). ``output``:
        "radiance" (linear, before tone mapping) or "display" (exposure, tone
        map and sRGB, in [0, 1]). The scene needs an albedo attribute.
        ``surface_depth``: surface depths for the shadow map and its receivers
        (docs/stages.md; None: the preset's, on; False: the splats' centre depths);
        ``map_surface_depth``: for the shadow map's occluders too (None: the
        preset's, off). ``shadow_fit``: "scene" (the map covers the scene's
        bounds), "view" (each camera's view within them: finer texels) or
        "cascades" (``shadow_cascades`` maps, 2 to 4, 3 by default, each over a
        slice of the camera's view depth: fine near the camera; pinhole cameras).
        ``host_depth``, ``depth_convention``, ``near``, ``far``: your meshes'
        depth, as ``render`` takes it; the splats behind it are hidden per pixel
        (their shadows stay), at the camera's size (not with the fast preset's
        half-size frames). ``background``: a constant radiance (r, g, b) where
        no splat covers a pixel instead of the environment; (0, 0, 0) gives
        premultiplied radiance, so ``image + (1 - alpha) * yours`` composites
        it over your frame. ``return_alpha``: return (image, alpha), alpha
        (N, H, W) the splats' coverage. ``shadow_cull``: splat the shadow map
        only where the call's frames look it up (the same shadows, for less
        when the sun or the cameras change from call to call, and less memory
        for large scenes; one map for the call's cameras, not kept for others).
        ``shadow_resolution`` (texels), ``shadow_k`` (sigmoid sharpness per
        metre), ``shadow_bias`` (metres), ``shadow_slope_bias`` and
        ``shadow_normal_offset`` (map texels), ``receiver_depth`` ("median" or
        "expected"), ``shadow_test`` ("sigmoid" or "traced"), ``shadow_filter``
        ("pcf": the four nearest texels' tests weighted bilinearly, or "depth":
        one test of the bilinear depth), ``map_coverage`` (the coverage a map
        texel's occluders must reach to cast shadow, strictly between 0 and 1;
        the presets' 0.6), ``receiver_coverage`` (the coverage a pixel's splats
        must reach to receive; the presets' 0.45): override the preset's (None
        keeps it), as ``srug relight``'s options of those names.
        """
        if background is not None:
            background = tuple(float(v) for v in background)
            if len(background) != 3:
                raise _invalid(f"background {background!r} is not r, g, b")
        if time is not None:
            if latitude is None or longitude is None:
                raise _invalid("time needs latitude and longitude")
            sun = sun_position(time, latitude, longitude)
        elif sun is not None:
            if len(sun) != 2:
                raise _invalid(f"sun {sun!r} is not (azimuth, elevation)")
            sun = (float(sun[0]), float(sun[1]))
        cb = _progress(progress, len(cameras), "frames")
        out = self._native.relight(
            scene._native,
            cameras._native,
            sun,
            float(sun_intensity),
            str(preset),
            None if environment is None else os.fspath(environment),
            float(env_rotation),
            float(env_intensity),
            float(exposure),
            str(output),
            cb,
            surface_depth=None if surface_depth is None else bool(surface_depth),
            shadow_fit=str(shadow_fit),
            host_depth=None if host_depth is None else np.ascontiguousarray(host_depth, dtype=np.float32),
            depth_convention=str(depth_convention),
            near=float(near),
            far=float(far),
            background=background,
            shadow_cull=bool(shadow_cull),
            shadow_resolution=None if shadow_resolution is None else int(shadow_resolution),
            shadow_k=None if shadow_k is None else float(shadow_k),
            shadow_bias=None if shadow_bias is None else float(shadow_bias),
            shadow_slope_bias=None if shadow_slope_bias is None else float(shadow_slope_bias),
            shadow_normal_offset=None if shadow_normal_offset is None else float(shadow_normal_offset),
            receiver_depth=None if receiver_depth is None else str(receiver_depth),
            shadow_test=None if shadow_test is None else str(shadow_test),
            shadow_filter=None if shadow_filter is None else str(shadow_filter),
            shadow_cascades=None if shadow_cascades is None else int(shadow_cascades),
            map_surface_depth=None if map_surface_depth is None else bool(map_surface_depth),
            map_coverage=None if map_coverage is None else float(map_coverage),
            receiver_coverage=None if receiver_coverage is None else float(receiver_coverage),
        )
        return (out[output], out["alpha"]) if return_alpha else out[output]

    def shadow(
        self,
        scene: Scene,
        camera: Cameras,
        sun: Tuple[float, float],
        *,
        resolution: int = 2048,
        k: float = 50.0,
        bias: float = 0.8,
        map_depth: Optional[str] = None,
        receiver_depth: Optional[str] = None,
        slope_bias: float = 3.0,
        normal_offset: float = 0.0,
        fit: str = "scene",
        tile: int = 16,
        filter: str = "pcf",
        surface_depth: bool = True,
        map_surface_depth: bool = False,
        map_coverage: Optional[float] = None,
        receiver_coverage: Optional[float] = None,
    ) -> "ShadowTest":
        """The differentiable sun shadow test for one camera (the paper's editable visibility):
        ``.visibility`` is V = sigmoid(k·(z_s − z + bias)) per pixel, (H, W) float32 (1 where no
        receiver); ``.backward(dl_dv)`` gives dL/d(every Gaussian's mean, log-scale, rotation,
        opacity logit) through the shadow map's occluders and the receivers. ``map_depth`` and
        ``receiver_depth``: "median" (the default, robust at silhouettes; its gradient reaches
        the means, and with surface depths the rotations and scales of each plane), "expected"
        (smooth; reaches opacities too) or, for the map,
        "expected-over-far" (docs/stages.md). ``slope_bias`` adds that many shadow-map texels
        times tan θ (θ: receiver normal to sun) to ``bias``; ``normal_offset`` moves each
        receiver that many texels times sin θ along its normal; the defaults (2048 texels, k 50,
        bias 0.8 m, slope bias 3, no normal offset, median depths, PCF, the receivers' surface
        depths) are the balanced preset's, as ``srug::shadow::ShadowSettings::default()``; the
        backward holds the normals they read fixed. ``surface_depth``: each receiver's depth where
        its pixel's ray meets the splat's plane (False: the splats' centre depths);
        ``map_surface_depth``: for the map's occluders too; both differentiated (docs/stages.md).
        ``map_coverage``: the coverage a map texel's occluders must reach for it to hold an
        occluder depth, ``receiver_coverage``: a pixel's splats for it to receive (median
        depths; None: the balanced preset's 0.6 and 0.45). ``filter``: "pcf" (V = Σ w_i·sigmoid(k·(z_i − z + bias)) over the four
        nearest texels, weighted bilinearly) or "depth" (one sigmoid of the bilinear depth). ``fit``: "scene" or "view" (the map covers the camera's view within the scene's
        bounds). ``tile``: the splat tile of the map and the receivers, 16 or 8 (8 makes the
        backward faster where splats crowd tiles; V is the same)."""
        if len(camera) != 1:
            raise _invalid(f"the shadow test takes one camera, not {len(camera)} (index the Cameras)")
        az, el = (float(v) for v in sun)
        return ShadowTest(
            self._native.shadow(
                scene._native,
                camera._native,
                (az, el),
                int(resolution),
                float(k),
                float(bias),
                map_depth,
                receiver_depth,
                slope_bias=float(slope_bias),
                normal_offset=float(normal_offset),
                fit=str(fit),
                tile=int(tile),
                filter=str(filter),
                surface_depth=bool(surface_depth),
                map_surface_depth=bool(map_surface_depth),
                map_coverage=None if map_coverage is None else float(map_coverage),
                receiver_coverage=None if receiver_coverage is None else float(receiver_coverage),
            )
        )

    def __repr__(self) -> str:
        return repr(self._native)


class ShadowTest:
    """One camera's shadow test from :meth:`Device.shadow`."""

    def __init__(self, native: "_srug.ShadowTest") -> None:
        self._native = native

    @property
    def visibility(self) -> np.ndarray:
        """V per pixel, (H, W) float32."""
        return self._native.visibility

    def backward(self, dl_dv: Any) -> Dict[str, np.ndarray]:
        """dL/d(means (G, 3), log_scales (G, 3), rotations (G, 4) w, x, y, z, opacity_logits (G,))
        from dL/dV (H, W)."""
        return self._native.backward(_float32(dl_dv, "dl_dv", self._native.shape))


def demo_city(gaussians: int = 200_000, seed: int = 7, sh_degree: int = 1) -> Tuple[Scene, Cameras]:
    """The built-in demo city (``srug demo``): a relightable scene and its street cameras."""
    scene, cams = _srug.demo_city(int(gaussians), int(seed), int(sh_degree))
    return Scene(scene), Cameras(_native=cams)


def sun_position(time: str, latitude: float, longitude: float) -> Tuple[float, float]:
    """The sun's (azimuth, elevation) in degrees at ``time`` (ISO 8601 with a zone) seen from
    ``latitude``, ``longitude`` (degrees, east positive), by NOAA's formulas."""
    return _srug.sun_position(str(time), float(latitude), float(longitude))
