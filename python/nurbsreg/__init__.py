"""nurbsreg: exact closest points on NURBS CAD models and ICP alignment of scans to them.

The same library calls as the ``nurbsreg`` command line, so the same numbers::

    import numpy as np, nurbsreg
    model = nurbsreg.load_model("examples/panel.json")       # JSON, STEP or IGES
    r = nurbsreg.project(model, np.array([[10.0, 20, 5], [50, 50, 30]]))
    r.distance, r.foot, r.entity, r.u, r.v, r.normal       # NumPy arrays, one row per point
    scan = nurbsreg.read_point_cloud("scan.pcd").points    # (N, 3) float64
    a = nurbsreg.align(model, scan)                         # from any pose, as the CLI
    a.T_model_scan, a.rms, a.fitness, a.deviation, a.fit.fit   # fit "good" (poor: raises)
    i = nurbsreg.inspect(model, "scan.pcd", tolerance=0.05, ply="deviations.ply")
    i.signed_distance, i.summary, i.passed                  # as ``nurbsreg inspect``

Points are (N, 3) float64 or float32 arrays of any memory layout. Long calls release the GIL
(other Python threads run meanwhile) and stop on Ctrl-C. ``threads=`` limits a call's worker
threads (None: all hardware threads); results never depend on it.
"""

import math as _math
import os as _os
import warnings as _warnings
from dataclasses import dataclass as _dataclass

import numpy as _np

from . import _core
from ._errors import AlignmentError, InputError, NurbsregWarning, OutputError, PoorFitError

__all__ = [
    "AlignmentError", "AlignmentResult", "Aligner", "CoarseReport", "FitVerdict", "InputError",
    "InspectionResult", "Model", "NurbsregWarning", "OutputError", "PointCloud", "PoorFitError",
    "PoseScore", "ProjectionResult", "SyntheticScan", "align", "inspect", "load_model",
    "project", "read_point_cloud", "synth", "write_point_cloud", "STATUS_OK", "STATUS_SKIPPED",
    "STATUS_NO_GEOMETRY", "STATUS_BEYOND_MAX_DISTANCE",
]
__version__ = _core.__version__

_core._register_types(InputError, OutputError)

Model = _core.Model
ProjectionResult = _core.ProjectionResult
AlignmentResult = _core.AlignmentResult
FitVerdict = _core.FitVerdict
CoarseReport = _core.CoarseReport
PoseScore = _core.PoseScore

#: ProjectionResult.status values.
STATUS_OK = 0
STATUS_SKIPPED = 1  # the point had a NaN or infinite coordinate
STATUS_NO_GEOMETRY = 2  # the model has nothing of the requested target kind
STATUS_BEYOND_MAX_DISTANCE = 3


def _warn_all(messages):
    for message in messages:
        _warnings.warn(message, NurbsregWarning, stacklevel=3)


def load_model(path):
    """Load a model: the project's JSON (``.json``), STEP (``.step``/``.stp``) or IGES
    (``.iges``/``.igs``, every face as an exact trimmed NURBS surface via OpenCASCADE).

    The model is prepared once (Bézier patches, bounds, hierarchy) and is then immutable: share
    it between threads and calls. ``model.info()`` gives what ``nurbsreg info --json`` prints
    (faces, patches, bounding box, skipped faces); ``model.units`` the length unit.

    Raises InputError (a ValueError) naming the file and the problem, as the CLI does; warns
    (NurbsregWarning) when faces of a CAD file could not be converted.
    """
    model = _core.load_model(_os.fspath(path))
    _warn_all(model.warnings)
    return model


def project(model, points, *, target="surfaces", threads=None, certify=False, hints=None):
    """Exact closest point on ``model`` of every row of ``points``, as ``nurbsreg project``.

    points: (N, 3) float64 or float32 array, C- or Fortran-ordered or strided: read in place,
        no copy (a list of points is converted to float64 first; a PointCloud gives its
        points). Rows with a NaN or infinite
        coordinate are skipped (status STATUS_SKIPPED, NaN results) and counted
        (``result.skipped``).
    target: "surfaces" or "curves".
    threads: worker threads for this call (None or 0: all hardware threads).
    certify: also make a warm-start certificate for every point, so that a later frame near
        this one, projected with ``hints=`` this result, skips most searches.
    hints: a ProjectionResult of the same model and length (e.g. the previous frame): speeds up
        the search; the answer is the same closest point (equal to a cold search's up to
        Newton's tolerance: within 1e-9 mm on the 100 mm example panel).

    Returns a ProjectionResult: read-only NumPy views of the engine's own arrays (no copy),
    ``foot`` (N, 3), ``distance``, ``signed_distance``, ``entity`` (int32, -1 if none), ``u``,
    ``v``, ``normal`` (N, 3), ``status`` (uint8, STATUS_*), ``on_trim_edge``. Identical for any
    thread count and to the CLI's rows. The GIL is released while it runs; Ctrl-C stops it.
    """
    if isinstance(points, PointCloud):
        points = points.points
    result = _core.project(model, points, target, threads, bool(certify), hints)
    _warn_all(result.warnings)
    return result


_ALIGN_DOC = """
    scan: (N, 3) float64 or float32 array (any layout; copied only when it is not C-ordered
        float64 or has NaN/infinite rows, which are skipped and counted in ``skipped``), or a
        :class:`PointCloud`.
    init: None (default): from any pose, as the CLI without ``--init``: the global coarse stage
        (features, sample consensus, hypotheses verified by exact ICP), then robust ICP from its
        winner. A 4x4 rigid matrix: exactly the CLI's ``--init`` (checked and made exactly
        orthonormal as a pose file is): local ICP from it, no global stage.
    global_alignment: None (default): the global stage exactly when ``init`` is None. False: the
        CLI's ``--no-global`` (ICP from ``init`` or from the identity). True: the CLI's
        ``--init auto`` (the global stage; contradicts ``init``, ValueError).
    distances: also return the exact signed distance of every aligned point
        (``result.signed_distance``, NaN for skipped rows).
    threads: worker threads for this call (None or 0: all hardware threads); the results do not
        depend on it.

    Returns an AlignmentResult: ``T_model_scan`` (4x4, model_point = T * scan_point),
    ``converged``, ``termination``, ``iterations``, ``rms``, ``inliers``, ``points``,
    ``fitness`` (inliers / points), ``fit`` (the verdict: a FitVerdict with ``fit`` "good" or
    "poor", ``inlier_fraction``, ``rms``, ``noise`` (the smaller of ``scan_noise`` and
    ``fit_noise``), ``rms_over_noise``, ``tolerance``,
    ``coverage``, ``reason``), ``coarse`` (the global stage's CoarseReport: ``method``,
    ``hypotheses``, ``verified``, ``winner`` and ``runner_up`` PoseScores, symmetric
    ``alternatives``, ``seconds``; None when it did not run), ``covariance`` (6x6),
    ``degeneracy``, ``history`` (one dict per iteration), ``deviation`` (mean, rms, median,
    p95, p99, max of |d| within max_distance), ``aligned`` (the scan moved onto the model, by
    input row), ``signed_distance`` (with distances=True), ``report()`` / ``to_json()`` (the
    CLI's ``align --report``, field for field; ``seconds`` is this call's wall time).

    Raises PoorFitError (an AlignmentError) when the fit verdict is poor, unless
    ``accept_poor=True`` (then it warns and returns the result, as ``--accept-poor``); raises
    AlignmentError when no pose could be found. Both carry the result (``.result``) and the
    message the CLI prints before it exits 1. ValueError/TypeError name a bad argument or
    option; NurbsregWarning where the CLI warns. Releases the GIL; Ctrl-C stops it.
"""

_OPTIONS_DOC = """
    The options are the CLI's, by the same names: ``method`` ("point-to-plane" or
    "point-to-point"), ``max_iterations`` (per stage, 50), ``max_distance`` (reject
    correspondences farther apart, model units; inf), ``keep_fraction`` (trimmed ICP, 1),
    ``kernel`` ("none", "huber", "tukey", "geman-mcclure"), ``kernel_scale`` (0: from the MAD),
    ``coarse`` (increasing subsample sizes); and the verdict's: ``accept_poor`` (a poor fit is
    returned with a warning instead of raised: ``--accept-poor``), ``min_inlier_fraction`` (a fit
    with fewer scan points within 3 x the scan's noise of the model is poor; 0.5). Bad values
    raise ValueError naming the option.
"""


def _global_mode(global_alignment):
    if global_alignment is None:
        return "auto"
    if global_alignment is True:
        return "on"
    if global_alignment is False:
        return "off"
    raise TypeError("global_alignment: expected None, True or False, got %r" % (global_alignment,))


def _checked(result):
    """The CLI's exit 1 as an exception; its warnings as warnings."""
    if result.failure is not None:
        fit = result.fit
        error = PoorFitError if fit is not None and not fit.good else AlignmentError
        raise error("scan: " + result.failure, result)
    _warn_all(result.warnings)
    return result


class Aligner:
    __doc__ = """Alignment of scans to one model, as ``nurbsreg align``; one Aligner keeps its
    warm state (per-point arrays, projection hints, the model's coarse-stage features) from
    frame to frame, so a sequence of frames aligns faster than fresh calls of :func:`align`.
    """ + _OPTIONS_DOC + """
    One ``align`` at a time per Aligner (calls from other threads wait); use one Aligner per
    thread to run in parallel.
    """

    def __init__(self, model, *, method="point-to-plane", max_iterations=50,
                 max_distance=_math.inf, keep_fraction=1.0, kernel="none", kernel_scale=0.0,
                 coarse=(), accept_poor=False, min_inlier_fraction=0.5):
        self._aligner = _core.Aligner(model, method, int(max_iterations), float(max_distance),
                                      float(keep_fraction), kernel, float(kernel_scale),
                                      [int(n) for n in coarse], bool(accept_poor),
                                      float(min_inlier_fraction))

    @property
    def model(self):
        """The model scans are aligned to."""
        return self._aligner.model

    def align(self, scan, init=None, *, global_alignment=None, distances=False, threads=None):
        if isinstance(scan, PointCloud):
            scan = scan.points
        return _checked(self._aligner.align(scan, init, _global_mode(global_alignment),
                                            bool(distances), threads))

    align.__doc__ = ("Align one scan: the rigid pose ``T_model_scan`` (model_point = T * "
                     "scan_point).\n" + _ALIGN_DOC)


def align(model, scan, *, init=None, global_alignment=None, distances=False, threads=None,
          accept_poor=False, min_inlier_fraction=0.5, **icp_options):
    return Aligner(model, accept_poor=accept_poor, min_inlier_fraction=min_inlier_fraction,
                   **icp_options).align(scan, init, global_alignment=global_alignment,
                                        distances=distances, threads=threads)


align.__doc__ = ("""Align ``scan`` to ``model``, as ``nurbsreg align`` (same pose, same report):
    ``Aligner(model, **options).align(scan, init, ...)``; for frame after frame keep one
    :class:`Aligner`.
""" + _ALIGN_DOC + _OPTIONS_DOC)


def _fitness(self):
    """Inliers / points (0 when there are no points)."""
    return self.inliers / self.points if self.points else 0.0


def _report(self):
    """The alignment report as ``nurbsreg align --report`` writes it (a dict, the CLI's fields
    and numbers; ``seconds`` is this call's wall time)."""
    import json
    return json.loads(self.report_json())


def _to_json(self):
    """The alignment report as the text ``nurbsreg align --report`` writes."""
    return self.report_json()


AlignmentResult.fitness = property(_fitness)
AlignmentResult.report = _report
AlignmentResult.to_json = _to_json


def inspect(model, scan, *, tolerance=None, tolerance_upper=None, tolerance_lower=None,
            init=None, pose=None, global_alignment=None, out_dir=None, ply=None, html=None,
            png=None, colour_scale="metrology", colour_min=None, colour_max=None,
            min_inside=0.99, viewer_points=300_000, model_mesh=True, exclude_beyond=None,
            threads=None, accept_poor=False, min_inlier_fraction=0.5, **icp_options):
    """Inspect a scan against ``model`` as ``nurbsreg inspect``: align it (unless ``pose`` is
    the final pose), then the signed deviation of every point, its statistics overall and per
    face, the pass/fail verdict, and the output files asked for.

    scan: a point-cloud file name (read as the CLI reads ``--scan``: the report names it and
        ``index`` is each point's position in the file), a :class:`PointCloud`, or an (N, 3)
        float64/float32 array (NaN/infinite rows are skipped and counted).
    tolerance: t > 0, the band [-t, +t] (model units); or ``tolerance_upper`` and
        ``tolerance_lower`` (signed) for an asymmetric band. One of the two is required.
    init, global_alignment, accept_poor, min_inlier_fraction and the ICP options (method,
        max_iterations, max_distance, keep_fraction, kernel, kernel_scale, coarse): the
        alignment, as :func:`align` (None: from any pose, the global stage first).
    pose: the final pose T (4x4, model_point = T * scan_point): no alignment, as ``--pose``.
    out_dir: write every output of the CLI into this folder (its parent must exist; all or
        nothing): inspect.json, inspect_faces.csv, deviations.ply, report.html, deviations.png.
    ply, html, png: without ``out_dir``, write just these: the coloured cloud (binary PLY with
        colours, signed_distance, face, u, v, tolerance, index), the self-contained HTML report,
        the PNG picture. Every file is written atomically.
    colour_scale ("metrology" or "blue-red"), colour_min, colour_max (where the colours
        saturate; default 3 x the band), min_inside (pass when at least this fraction of the
        points is inside; 0.99), viewer_points (at most this many points in the HTML's 3-D
        view), model_mesh (the model's faces in grey in the HTML and PNG): as the CLI.
    exclude_beyond: leave out the points farther than this from the model (clutter such as a
        fixture; model units, beyond the band), counted in ``excluded`` and in every output, as
        ``--exclude-beyond``. Without it, a warning says when far points alone decide the
        verdict.
    threads: worker threads (None or 0: all hardware threads).

    Returns an InspectionResult: per inspected point (one row each, scan order; points without
    a foot on the model are left out and counted in ``unprojected``, those beyond
    ``exclude_beyond`` in ``excluded``) ``points`` (N, 3, aligned,
    model coordinates), ``signed_distance``, ``face``, ``u``, ``v``, ``index`` (row in the file
    or input array); ``summary`` (points, inside, below, above, inside_tolerance, mean, std,
    rms, min, max, p5, p95), ``faces`` (the same per face), ``tolerance`` (lower, upper),
    ``passed``, ``alignment`` (the AlignmentResult; None with ``pose``), ``report()`` /
    ``to_json()`` (inspect.json's fields and numbers) and ``faces_csv()``.

    Raises PoorFitError / AlignmentError (with ``.result``) when the alignment gives no pose to
    use, as the CLI exits 1 (no file is written then); ValueError naming a bad argument;
    InputError for a bad scan file; OutputError when a file cannot be written. Releases the
    GIL; Ctrl-C stops the alignment.
    """
    if tolerance is None and (tolerance_upper is None or tolerance_lower is None):
        raise ValueError("tolerance is required (or both tolerance_upper and tolerance_lower)")
    if tolerance is not None and not (float(tolerance) > 0 and _math.isfinite(tolerance)):
        raise ValueError("tolerance: must be a positive number (got %r)" % (tolerance,))
    upper = float(tolerance_upper if tolerance_upper is not None else tolerance)
    lower = float(tolerance_lower if tolerance_lower is not None else -tolerance)
    index, file_skipped, name = None, 0, ""
    if isinstance(scan, (str, bytes, _os.PathLike)):
        name = _os.fsdecode(scan)
        scan = read_point_cloud(name)
        if len(scan.points) == 0:
            raise InputError(name + ": no finite points to inspect")
    if isinstance(scan, PointCloud):
        index, file_skipped, scan = scan.index, scan.skipped, scan.points
    aligner = Aligner(model, accept_poor=accept_poor, min_inlier_fraction=min_inlier_fraction,
                      **icp_options)
    paths = [None if p is None else _os.fspath(p) for p in (out_dir, ply, html, png)]
    if paths[0] is not None and any(p is not None for p in paths[1:]):
        raise ValueError("out_dir writes every output; ply, html and png are for single files")
    result = _core.inspect(
        aligner._aligner, scan, index, int(file_skipped), name, init, pose,
        _global_mode(global_alignment), lower, upper, colour_scale,
        None if colour_min is None else float(colour_min),
        None if colour_max is None else float(colour_max), float(min_inside), int(viewer_points),
        bool(model_mesh), None if exclude_beyond is None else float(exclude_beyond), paths[0], *(p or "" for p in paths[1:]), threads)
    if result.alignment is not None:
        _checked(result.alignment)
    _warn_all(result.warnings)
    return result


InspectionResult = _core.InspectionResult


def _inspection_report(self):
    """inspect.json as a dict: the alignment report's fields, "tolerance", the overall
    statistics at the top level, "faces", "verdict" (the CLI's, number for number)."""
    import json
    return json.loads(self.report_json())


InspectionResult.report = _inspection_report
InspectionResult.to_json = lambda self: self.report_json()
InspectionResult.to_json.__doc__ = "inspect.json's text."


@_dataclass
class PointCloud:
    """A point-cloud file as arrays: ``points`` (N, 3) float64, the finite points in file order;
    ``index`` (N,) uint64, each point's 0-based position in the file; ``skipped`` points dropped
    for a NaN or infinite coordinate; ``total`` points in the file; ``width`` x ``height`` of an
    organised scan (unorganised: total x 1)."""

    points: _np.ndarray
    index: _np.ndarray
    skipped: int
    total: int
    width: int
    height: int


def read_point_cloud(path):
    """Read a PCD (ascii, binary, binary_compressed), PLY (ascii, binary) or XYZ/TXT/CSV file,
    as the CLI does. Raises InputError naming the file (and line or field)."""
    return PointCloud(**_core.read_point_cloud(_os.fspath(path)))


def write_point_cloud(path, points, *, encoding="binary", double_precision=False):
    """Write points by extension: .pcd (``encoding`` "binary", "ascii" or "binary_compressed"),
    .ply (binary), .xyz/.txt, .csv; float32 coordinates unless ``double_precision``. Atomic
    (no partial file); raises OutputError (an OSError) on failure."""
    if isinstance(points, PointCloud):
        points = points.points
    _core.write_point_cloud(_os.fspath(path), points, encoding, bool(double_precision))


@_dataclass
class SyntheticScan:
    """A synthetic scan: ``points`` (N, 3) in the scan frame, ``T_model_scan`` (4x4, the pose
    an alignment must recover), and per point ``on_model`` (False for outliers), the source
    ``surface`` and its exact ``uv`` (N, 2) before noise."""

    points: _np.ndarray
    T_model_scan: _np.ndarray
    on_model: _np.ndarray
    surface: _np.ndarray
    uv: _np.ndarray


def synth(model, points, *, noise=0.0, pose=None, seed=1, outliers=0.0, view_fraction=1.0,
          view_direction=(0.0, 0.0, 1.0), fixture=0.0, fixture_up=(0.0, 0.0, 1.0)):
    """A synthetic scan of ``model`` as ``nurbsreg synth``: ``points`` area-uniform samples,
    Gaussian ``noise`` (sigma, model units) along the normal, scanner ``pose`` (rx, ry, rz
    degrees about x, y, z, then tx, ty, tz: scan_point = pose * model_point), ``seed``, a
    fraction of ``outliers`` (uniform in the scan's box), a partial view (``view_fraction`` of
    the model seen from ``view_direction``), a ``fixture`` fraction on a plane under the part
    (below it along ``fixture_up``). Same options, same points as the CLI."""
    if pose is not None:
        pose = [float(x) for x in pose]
        if len(pose) != 6:
            raise ValueError("pose: expected 6 numbers (rx ry rz tx ty tz), got %d" % len(pose))
    direction = [float(x) for x in view_direction]
    if len(direction) != 3:
        raise ValueError("view_direction: expected 3 numbers, got %d" % len(direction))
    up = [float(x) for x in fixture_up]
    if len(up) != 3:
        raise ValueError("fixture_up: expected 3 numbers, got %d" % len(up))
    return SyntheticScan(**_core.synth(model, int(points), float(noise), pose, int(seed),
                                       float(outliers), float(view_fraction), direction,
                                       float(fixture), up))
