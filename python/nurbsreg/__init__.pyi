# Type stubs of the nurbsreg package (the compiled nurbsreg._core and its Python wrappers).
import os
from dataclasses import dataclass
from typing import Any, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

PathLike = Union[str, os.PathLike[str]]
# (N, 3) float64 or float32, any memory layout; or a nested sequence of numbers.
Points = Union[npt.NDArray[np.float64], npt.NDArray[np.float32], Sequence[Sequence[float]]]

STATUS_OK: int
STATUS_SKIPPED: int
STATUS_NO_GEOMETRY: int
STATUS_BEYOND_MAX_DISTANCE: int

class InputError(ValueError): ...
class OutputError(OSError): ...

class AlignmentError(RuntimeError):
    result: Optional[AlignmentResult]
    def __init__(self, message: str, result: Optional[AlignmentResult] = ...) -> None: ...

class PoorFitError(AlignmentError): ...

class NurbsregWarning(UserWarning): ...

class FitVerdict:
    @property
    def fit(self) -> str: ...  # "good" or "poor"
    good: bool
    noise: float
    tolerance: float
    inlier_fraction: float
    rms: float
    rms_over_noise: float
    coverage: float
    reason: str

class PoseScore:
    @property
    def T_model_scan(self) -> npt.NDArray[np.float64]: ...  # (4, 4)
    inlier_fraction: float
    trimmed_rms: float

class CoarseReport:
    method: str
    scan_keypoints: int
    model_keypoints: int
    matches: int
    hypotheses: int
    verified: int
    voxel: float
    noise: float
    winner: PoseScore
    runner_up: Optional[PoseScore]
    alternatives: list[PoseScore]
    symmetry: str
    seconds: float

class Model:
    @property
    def path(self) -> str: ...
    @property
    def units(self) -> str: ...
    @property
    def surface_count(self) -> int: ...
    @property
    def curve_count(self) -> int: ...
    @property
    def patch_count(self) -> int: ...
    @property
    def bounds(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    @property
    def control_point_box(self) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
    @property
    def warnings(self) -> list[str]: ...
    def info(self) -> dict[str, Any]: ...

class ProjectionResult:
    @property
    def foot(self) -> npt.NDArray[np.float64]: ...  # (N, 3)
    @property
    def distance(self) -> npt.NDArray[np.float64]: ...
    @property
    def signed_distance(self) -> npt.NDArray[np.float64]: ...
    @property
    def entity(self) -> npt.NDArray[np.int32]: ...
    @property
    def u(self) -> npt.NDArray[np.float64]: ...
    @property
    def v(self) -> npt.NDArray[np.float64]: ...
    @property
    def normal(self) -> npt.NDArray[np.float64]: ...  # (N, 3)
    @property
    def status(self) -> npt.NDArray[np.uint8]: ...
    @property
    def on_trim_edge(self) -> npt.NDArray[np.uint8]: ...
    @property
    def skipped(self) -> int: ...
    @property
    def target(self) -> str: ...
    @property
    def warnings(self) -> list[str]: ...
    def __len__(self) -> int: ...

class AlignmentResult:
    @property
    def T_model_scan(self) -> npt.NDArray[np.float64]: ...  # (4, 4)
    @property
    def converged(self) -> bool: ...
    @property
    def termination(self) -> str: ...
    @property
    def message(self) -> str: ...
    @property
    def iterations(self) -> int: ...
    @property
    def rms(self) -> float: ...
    @property
    def inliers(self) -> int: ...
    @property
    def points(self) -> int: ...
    @property
    def skipped(self) -> int: ...
    @property
    def fitness(self) -> float: ...
    @property
    def seconds(self) -> float: ...
    @property
    def covariance(self) -> npt.NDArray[np.float64]: ...  # (6, 6)
    @property
    def degeneracy(self) -> dict[str, Any]: ...
    @property
    def history(self) -> list[dict[str, Any]]: ...
    @property
    def deviation(self) -> dict[str, float]: ...
    @property
    def failure(self) -> Optional[str]: ...
    @property
    def fit(self) -> Optional[FitVerdict]: ...  # None when there was no pose to judge
    @property
    def coarse(self) -> Optional[CoarseReport]: ...  # None when the global stage did not run
    @property
    def scan_size(self) -> float: ...
    @property
    def model_size(self) -> float: ...
    @property
    def aligned(self) -> npt.NDArray[np.float64]: ...  # (N, 3), by input row
    @property
    def signed_distance(self) -> Optional[npt.NDArray[np.float64]]: ...
    @property
    def warnings(self) -> list[str]: ...
    def report(self) -> dict[str, Any]: ...
    def report_json(self) -> str: ...
    def to_json(self) -> str: ...

def load_model(path: PathLike) -> Model: ...
def project(model: Model, points: Union[Points, PointCloud], *, target: str = ...,
            threads: Optional[int] = ..., certify: bool = ...,
            hints: Optional[ProjectionResult] = ...) -> ProjectionResult: ...

class Aligner:
    def __init__(self, model: Model, *, method: str = ..., max_iterations: int = ...,
                 max_distance: float = ..., keep_fraction: float = ..., kernel: str = ...,
                 kernel_scale: float = ..., coarse: Sequence[int] = ...,
                 accept_poor: bool = ..., min_inlier_fraction: float = ...) -> None: ...
    @property
    def model(self) -> Model: ...
    def align(self, scan: Union[Points, PointCloud], init: Optional[npt.ArrayLike] = ..., *,
              global_alignment: Optional[bool] = ..., distances: bool = ...,
              threads: Optional[int] = ...) -> AlignmentResult: ...

def align(model: Model, scan: Union[Points, PointCloud], *, init: Optional[npt.ArrayLike] = ...,
          global_alignment: Optional[bool] = ..., distances: bool = ...,
          threads: Optional[int] = ..., accept_poor: bool = ...,
          min_inlier_fraction: float = ..., method: str = ...,
          max_iterations: int = ..., max_distance: float = ..., keep_fraction: float = ...,
          kernel: str = ..., kernel_scale: float = ..., coarse: Sequence[int] = ...
          ) -> AlignmentResult: ...

@dataclass
class PointCloud:
    points: npt.NDArray[np.float64]
    index: npt.NDArray[np.uint64]
    skipped: int
    total: int
    width: int
    height: int

def read_point_cloud(path: PathLike) -> PointCloud: ...
def write_point_cloud(path: PathLike, points: Union[Points, PointCloud], *, encoding: str = ...,
                      double_precision: bool = ...) -> None: ...

@dataclass
class SyntheticScan:
    points: npt.NDArray[np.float64]
    T_model_scan: npt.NDArray[np.float64]
    on_model: npt.NDArray[np.bool_]
    surface: npt.NDArray[np.int32]
    uv: npt.NDArray[np.float64]

def synth(model: Model, points: int, *, noise: float = ..., pose: Optional[Sequence[float]] = ...,
          seed: int = ..., outliers: float = ..., view_fraction: float = ...,
          view_direction: Sequence[float] = ...) -> SyntheticScan: ...

class InspectionResult:
    @property
    def alignment(self) -> Optional[AlignmentResult]: ...  # None when the pose was given
    @property
    def inspected(self) -> bool: ...
    @property
    def points(self) -> npt.NDArray[np.float64]: ...  # (N, 3) aligned, model coordinates
    @property
    def signed_distance(self) -> npt.NDArray[np.float64]: ...
    @property
    def face(self) -> npt.NDArray[np.int32]: ...
    @property
    def u(self) -> npt.NDArray[np.float64]: ...
    @property
    def v(self) -> npt.NDArray[np.float64]: ...
    @property
    def index(self) -> npt.NDArray[np.uint64]: ...  # row in the scan file or input array
    @property
    def skipped(self) -> int: ...
    @property
    def unprojected(self) -> int: ...
    @property
    def summary(self) -> dict[str, float]: ...
    @property
    def faces(self) -> list[dict[str, Any]]: ...
    @property
    def tolerance(self) -> tuple[float, float]: ...
    @property
    def passed(self) -> bool: ...
    @property
    def warnings(self) -> list[str]: ...
    def report(self) -> dict[str, Any]: ...
    def report_json(self) -> str: ...
    def to_json(self) -> str: ...
    def faces_csv(self) -> str: ...
    def __len__(self) -> int: ...

def inspect(model: Model, scan: Union[PathLike, Points, PointCloud], *,
            tolerance: Optional[float] = ..., tolerance_upper: Optional[float] = ...,
            tolerance_lower: Optional[float] = ..., init: Optional[npt.ArrayLike] = ...,
            pose: Optional[npt.ArrayLike] = ..., global_alignment: Optional[bool] = ...,
            out_dir: Optional[PathLike] = ..., ply: Optional[PathLike] = ...,
            html: Optional[PathLike] = ..., png: Optional[PathLike] = ...,
            colour_scale: str = ..., colour_min: Optional[float] = ...,
            colour_max: Optional[float] = ..., min_inside: float = ..., viewer_points: int = ...,
            model_mesh: bool = ..., threads: Optional[int] = ..., accept_poor: bool = ...,
            min_inlier_fraction: float = ..., method: str = ..., max_iterations: int = ...,
            max_distance: float = ..., keep_fraction: float = ..., kernel: str = ...,
            kernel_scale: float = ..., coarse: Sequence[int] = ...) -> InspectionResult: ...
