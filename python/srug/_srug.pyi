"""The native half of the srug package (PyO3). Use the `srug` package's classes instead."""

from typing import Any, Callable, Dict, List, Optional, Tuple

import numpy as np

class Error(Exception):
    """A srug error; `kind` is one of invalid_argument, io, bad_file, environment, gpu, internal."""

    kind: str

class Device:
    def __init__(self, device: Optional[str] = None, validation: Optional[bool] = None) -> None: ...
    @property
    def name(self) -> str: ...
    @property
    def validation(self) -> bool: ...
    def take_validation_messages(self) -> List[str]: ...
    def close(self) -> None: ...
    @property
    def closed(self) -> bool: ...
    def memory(self) -> Dict[str, int]: ...
    def release_pooled_memory(self) -> int: ...
    def last_timings(self) -> List[List[Tuple[str, float]]]: ...
    def load_scene(self, path: str, order: str = ...) -> Scene: ...
    def render(
        self,
        scene: Scene,
        cameras: Cameras,
        channels: List[str],
        background: Tuple[float, float, float] = ...,
        sh_degree: Optional[int] = ...,
        tile: int = ...,
        progress: Optional[Callable[[int, int], Any]] = ...,
        surface_depth: bool = ...,
        host_depth: Optional[np.ndarray] = ...,
        depth_convention: str = ...,
        near: float = ...,
        far: float = ...,
        median_coverage: float = ...,
    ) -> Dict[str, np.ndarray]: ...
    def relight(
        self,
        scene: Scene,
        cameras: Cameras,
        sun: Optional[Tuple[float, float]] = ...,
        sun_intensity: float = ...,
        preset: str = ...,
        environment: Optional[str] = ...,
        env_rotation: float = ...,
        env_intensity: float = ...,
        exposure: float = ...,
        output: str = ...,
        progress: Optional[Callable[[int, int], Any]] = ...,
        surface_depth: Optional[bool] = ...,
        shadow_fit: str = ...,
        host_depth: Optional[np.ndarray] = ...,
        depth_convention: str = ...,
        near: float = ...,
        far: float = ...,
        background: Optional[Tuple[float, float, float]] = ...,
        shadow_cull: bool = ...,
        shadow_resolution: Optional[int] = ...,
        shadow_k: Optional[float] = ...,
        shadow_bias: Optional[float] = ...,
        shadow_slope_bias: Optional[float] = ...,
        shadow_normal_offset: Optional[float] = ...,
        receiver_depth: Optional[str] = ...,
        shadow_test: Optional[str] = ...,
        shadow_filter: Optional[str] = ...,
        shadow_cascades: Optional[int] = ...,
        map_surface_depth: Optional[bool] = ...,
        map_coverage: Optional[float] = ...,
        receiver_coverage: Optional[float] = ...,
    ) -> Dict[str, np.ndarray]: ...

    def shadow(
        self,
        scene: Scene,
        camera: Cameras,
        sun: Tuple[float, float],
        resolution: int = ...,
        k: float = ...,
        bias: float = ...,
        map_depth: Optional[str] = ...,
        receiver_depth: Optional[str] = ...,
        sun_intensity: float = ...,
        slope_bias: float = ...,
        normal_offset: float = ...,
        fit: str = ...,
        tile: int = ...,
        filter: str = ...,
        surface_depth: bool = ...,
        map_surface_depth: bool = ...,
        map_coverage: Optional[float] = ...,
        receiver_coverage: Optional[float] = ...,
    ) -> ShadowTest: ...

class ShadowTest:
    @property
    def shape(self) -> Tuple[int, int]: ...
    @property
    def visibility(self) -> np.ndarray: ...
    def backward(self, dl_dv: np.ndarray) -> Dict[str, np.ndarray]: ...

class Scene:
    @staticmethod
    def from_file(path: str, order: str = ...) -> Scene: ...
    @staticmethod
    def from_arrays(
        means: np.ndarray,
        quats: np.ndarray,
        scales: np.ndarray,
        opacities: np.ndarray,
        sh: np.ndarray,
        activated: bool = ...,
        normals: Optional[np.ndarray] = ...,
        albedo: Optional[np.ndarray] = ...,
        roughness: Optional[np.ndarray] = ...,
        metallic: Optional[np.ndarray] = ...,
        ao: Optional[np.ndarray] = ...,
        visibility: Optional[np.ndarray] = ...,
        order: str = ...,
    ) -> Scene: ...
    def save(self, path: str, format: Optional[str] = ...) -> None: ...
    def arrays(self) -> Dict[str, np.ndarray]: ...
    @property
    def count(self) -> int: ...
    def __len__(self) -> int: ...
    @property
    def sh_degree(self) -> int: ...
    @property
    def relightable(self) -> bool: ...
    @property
    def bounds(self) -> Optional[Tuple[Tuple[float, float, float], Tuple[float, float, float]]]: ...

class Cameras:
    def __init__(
        self,
        viewmats: np.ndarray,
        ks: np.ndarray,
        width: int,
        height: int,
        near: float = ...,
        far: float = ...,
        names: Optional[List[str]] = ...,
    ) -> None: ...
    @staticmethod
    def from_file(path: str) -> Cameras: ...
    def resized(self, width: int, height: int) -> Cameras: ...
    def panoramas(self, width: int) -> Cameras: ...
    def select(self, indices: List[int]) -> Cameras: ...
    def __len__(self) -> int: ...
    @property
    def names(self) -> List[str]: ...
    @property
    def sizes(self) -> List[Tuple[int, int]]: ...
    @property
    def lenses(self) -> List[str]: ...
    @property
    def viewmats(self) -> np.ndarray: ...
    @property
    def ks(self) -> np.ndarray: ...

def version() -> str: ...
def demo_city(gaussians: int = ..., seed: int = ..., sh_degree: int = ...) -> Tuple[Scene, Cameras]: ...
def sun_position(time: str, latitude: float, longitude: float) -> Tuple[float, float]: ...
