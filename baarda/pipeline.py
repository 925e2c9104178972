"""One pipeline for every input: read, prepare (CRS, approximations, datum), adjust.

    block = read("project/")            # native, COLMAP, BAL, DBAT, PhotoModeler, AICON
    result = adjust(block)              # what `baarda adjust project/` does
    qc = assess(result)                 # statistics of every observation
    qc = snoop(block)                   # iterative data snooping
    bq = adjust_models(read_models("models/"))   # independent models (FOTEF)

`prepare` makes the choices that the command line used to make on its own: a block with a
CRS is adjusted in a local east-north-up frame of it (block/crs.py; results are written
back in the CRS), photos without approximate orientations are resected from the control
(bundle/resection.py), and the datum is the control when there is control, else a free
network by minimal constraints (bundle/free_network.py; observations of points behind a
camera at the approximations are then left out).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from baarda.block.control import with_check_points
from baarda.block.model_block import ModelBlock
from baarda.block.model_deformations import ALL as ALL_DEFORMATIONS
from baarda.block.photo_block import Block
from baarda.errors import GeometryError, ProjectError
from baarda.io.formats import read_any
from baarda.io.text_files import ENCODING
from baarda.options import (
    FREE_DATUMS,
    Config,
    Progress,
    Requested,
    ScreeningOptions,
    SolveOptions,
    TestOptions,
)

# The computation (numba kernels, SciPy's distributions, pyproj) is imported by the step
# that needs it: reading a file, and failing on a bad one, costs only the reader's imports.
if TYPE_CHECKING:
    from baarda.bundle.bundle_problem import BundleProblem
    from baarda.bundle.bundle_result import BundleResult
    from baarda.independent.model_hypotheses import UserHypotheses
    from baarda.independent.workflow import BlockQuality
    from baarda.quality.assessment import Assessment
    from baarda.screening.chain import ScreeningResult


def read(path: str | Path, fmt: str | None = None, *, crs: str | None = None,
         pixel_mm: float | None = None, sigma_px: float | None = None,
         sigma_image_um: float | None = None, datum: str | None = None,
         encoding: str = ENCODING, camera_model: str | None = None,
         calibrate=None, camera: str | Path | None = None,
         calibration_group: str | None = None, check_gcp=None,
         control: str | Path | None = None, gcp_list: str | Path | None = None,
         model: int | None = None, tie_points: str | Path | None = None) -> Block:
    """Read any supported input (io/formats.py) into a Block, configured as asked.

    crs: the CRS of the ground coordinates (overrides project.toml); sigma_image_um or
    sigma_px: the image sigma [µm] or [px] of every observation of any input (default: the
    input's own), pixel_mm: the pixel size [mm] of inputs without one (io/image_sigma.py
    says which option applies to which format; one that does not is an error); datum:
    "control", "free" or "inner" (overrides the input's: see prepare); encoding: of the
    input's text files (default UTF-8); camera_model: put every camera on this model
    (block/camera_models.py); calibrate: the camera parameters to estimate, a list of names
    ('c', 'x0', 'y0', the model's coefficients) for every camera, "all" or "none" (default:
    what the input says: project.toml [calibration], or what the source program estimated);
    camera: a DBAT camera file (e.g. DBAT's calibration result) replacing a DBAT script's
    camera (it is still estimated where the script estimates it, unless calibrate="none");
    calibration_group: "strip" estimates the camera parameters per camera and strip
    (block/camera.py cameras_per_strip), "camera" shares them (both override project.toml),
    None as the input says; check_gcp:
    control points to use as check points (with_check_points), e.g. an OpenSfM dataset's
    GCPs; control: a control file (DBAT's text format or a native ground_points.csv,
    io/control_file.py) whose points replace the input's control, matched by id
    (block/control.py); gcp_list: OpenDroneMap's gcp_list.txt, GCPs measured on the images
    added as control points, the block moved into their CRS (with_gcp_list; `check_gcp`
    names those that are check points); model: of a file with several (NVM, 0-based;
    default the first); tie_points: a Bundler file of the same chunk joining a Metashape
    cameras XML's markers (io/metashape_cameras.py).
    The settings are resolved once (io/configuration.py: the rule of
    each); `read_configured` returns the configuration too.
    """
    requested = Requested(crs=crs, pixel_mm=pixel_mm, sigma_px=sigma_px,
                          sigma_image_um=sigma_image_um, datum=datum,
                          camera_model=camera_model,
                          calibrate=tuple(calibrate) if isinstance(calibrate, list)
                          else calibrate, calibration_group=calibration_group)
    return read_configured(path, fmt, requested, encoding=encoding, camera=camera,
                           check_gcp=check_gcp, control=control, gcp_list=gcp_list,
                           model=model, tie_points=tie_points)[0]


def read_configured(path: str | Path, fmt: str | None = None,
                    requested: Requested | None = None, *, encoding: str = ENCODING,
                    camera: str | Path | None = None, check_gcp=None,
                    control: str | Path | None = None, gcp_list: str | Path | None = None,
                    model: int | None = None,
                    tie_points: str | Path | None = None) -> tuple[Block, Config]:
    """(the block, the run's configuration): the input read (io/formats.py), its control
    replaced (`control`), GCP image measurements added (`gcp_list`: with_gcp_list), control
    points turned into check points (`check_gcp`: see `read`), and what
    the command line or the API asks for (`requested`) merged once with the input's
    settings (io/configuration.resolve_config) and applied to the block (`configure`).
    Every command reads its input here; `prepare` and the tests take the configuration."""
    from baarda.io.configuration import check_requested, configure, resolve_config
    from baarda.io.formats import detect

    r = requested or Requested()
    check_requested(r)  # before reading: a bad value costs nothing
    if control is not None and gcp_list is not None:
        raise ProjectError("command line", "--control and --gcp-list both replace the input's "
                           "control: give the control in one of them (a gcp_list.txt holds "
                           "the GCPs' coordinates and their image measurements)")
    fmt = fmt or detect(path)
    block = read_any(path, fmt, pixel_mm=r.pixel_mm, sigma_px=r.sigma_px,
                     sigma_image_um=r.sigma_image_um, encoding=encoding, camera=camera,
                     crs=r.crs, model=model, tie_points=tie_points)
    if control is not None:
        from baarda.block.control import with_control
        from baarda.io.control_file import read_control_file

        cf = read_control_file(control, encoding, block.settings.sigma_control_m)
        block = with_control(block, cf.ids, cf.xyz, cf.sigma, cf.role, cf.path)
    if gcp_list is not None:
        from baarda.gcp_placement import with_gcp_list

        block = with_gcp_list(block, gcp_list, encoding, r.crs)
    if check_gcp is not None:
        block = with_check_points(block, check_gcp)
    config = resolve_config(r, block, fmt)
    return configure(block, config), config


def with_approximations(block: Block) -> Block:
    """The block with approximate orientations of the photos that have none (DBAT scripts),
    by space resection from the control and intersection (bundle/resection.py)."""
    missing = ~np.isfinite(block.photos.eo).all(axis=1)
    if not missing.any():
        return block
    from baarda.bundle.resection import orient_block

    eo = orient_block(block)
    photos = replace(block.photos, eo=eo)
    return replace(block, photos=photos, notes=list(block.notes) + [
        f"approximate orientations of {int(missing.sum())} photo(s) by space resection"])


def as_design(block: Block) -> Block:
    """A block as read, as the design of a plan (baarda plan --project, modified
    snooping): in the local frame of its CRS, photos without orientation oriented by space
    resection (the geometry the bundle would see)."""
    return with_approximations(localized(block))


def with_tie_coordinates(block: Block) -> Block:
    """The block in a local frame of its CRS (`localized`) with every tie point that has
    no coordinates intersected from the photos' orientations (bundle/geometry.py), for
    the writers of formats that store both (output/format_files.write_opensfm)."""
    return with_intersected_ties(localized(block))


def with_intersected_ties(block: Block) -> Block:
    """The block with every tie point that has no coordinates intersected from the photos'
    orientations (bundle/geometry.py), in the block's own frame, noted; GeometryError naming
    the points that cannot be intersected (`baarda convert --to` a format that stores
    points)."""
    from baarda.bundle.geometry import intersect

    pts = block.points
    need = np.flatnonzero((pts.role == "tie") & ~np.isfinite(pts.xyz).all(axis=1))
    if not len(need):
        return block
    xyz = pts.xyz.copy()
    xyz[need] = intersect(block, block.photos.eo, need)
    lost = need[~np.isfinite(xyz[need]).all(axis=1)]
    if len(lost):
        keep = np.ones(len(pts), bool)
        keep[lost] = False
        raise GeometryError(f"{len(lost)} tie point(s) cannot be intersected: "
                            + ", ".join(pts.ids[j] for j in lost[:10]))
    return replace(block, points=replace(pts, xyz=xyz), notes=list(block.notes) + [
        f"{len(need)} tie point(s) without coordinates intersected from the orientations"])


def localized(block: Block) -> Block:
    """The block in a local east-north-up frame of its CRS when it has one (block/crs.py)."""
    if not block.settings.crs or block.frame is not None:
        return block
    from baarda.block.crs import localize

    return localize(block)


def prepare(block: Block, free: bool | None = None, *,
            solve: SolveOptions | str | None = None,
            config: Config | None = None) -> BundleProblem:
    """The bundle problem of a block as read: local frame, approximations, datum.

    The datum is the control unless the block is a free network (`free`, default: the
    block's settings.datum: "free" for inputs without control by nature, COLMAP, BAL and
    AICON, or `datum = "free"` in project.toml; "inner": a free network whose coordinates
    are given in the inner datum of all its points, bundle/inner_datum.py).  A block that
    should have control and has too little is a GeometryError that names what is missing.
    In a free network, control points become check points (their differences refer to the
    free datum).  `solve`: the solver's options for every fit of the problem, or their
    name (bundle_problem.DAMPING: "gn" Gauss-Newton with step halving, the default; "lm"
    Levenberg-Marquardt).  `config`: the run's configuration (read_configured): its datum
    and solver unless `free` and `solve` say otherwise."""
    from baarda.bundle.bundle_problem import DAMPING

    if config is not None:
        solve = config.solver if solve is None else solve
        if free is None and config.datum != block.settings.datum:
            block = replace(block, settings=replace(block.settings, datum=config.datum))
    if isinstance(solve, str):
        if solve not in DAMPING:
            raise ValueError(f"unknown solver {solve!r}: one of {', '.join(DAMPING)}")
        solve = DAMPING[solve]
    problem = _prepare(block, free)
    return problem if solve is None else problem.with_solve_options(solve)


def _prepare(block: Block, free: bool | None) -> BundleProblem:
    from baarda.block.camera import ideal_image_coordinates
    from baarda.bundle.bundle_problem import BundleProblem
    from baarda.bundle.diagnostics import diagnose
    from baarda.bundle.free_network import (
        FreeBundleProblem,
        drop_points_behind,
        observed_datum_share,
        without_weak_datum_observations,
    )
    from baarda.bundle.geometry import intersected_points

    inner = block.settings.datum == "inner"
    free = block.settings.datum in FREE_DATUMS if free is None else free
    block = with_approximations(localized(block))
    ideal = ideal_image_coordinates(block)  # once: distortion-free image coordinates
    xyz = intersected_points(block, ideal)  # once, for the diagnosis and the approximations
    diagnosis = tuple(diagnose(block, xyz, ideal))
    if not free:
        return BundleProblem(block, diagnosis=diagnosis, intersected=xyz)
    if block.points.controlled.any():
        block = as_check_points(block)  # the same rays: the same intersections
    block, dropped = drop_points_behind(block)
    share = observed_datum_share(block)  # once: for both (None where they leave it out)
    block = without_weak_datum_observations(block, share)
    return FreeBundleProblem(block, diagnosis=diagnosis, inner=inner,
                             intersected=None if dropped else xyz,
                             share=None if share is None or share.weak else share)


def as_check_points(block: Block) -> Block:
    """The block with its control points turned into check points (a free network)."""
    pts = block.points
    ctrl = pts.role == "control"
    full = np.isfinite(pts.xyz).all(axis=1)
    role = np.where(ctrl, np.where(full, "check", "tie"), pts.role).astype(object)
    xyz = np.where((ctrl & ~full)[:, None], np.nan, pts.xyz)  # tie points: intersected
    points = replace(pts, xyz=xyz, role=role,  # a check point's sigma: its survey's accuracy
                     sigma=np.where((ctrl & ~full)[:, None], np.nan, pts.sigma))
    return replace(block, points=points, notes=list(block.notes) + [
        f"free network: {int(ctrl.sum())} control point(s) used as check points only (their "
        "differences refer to the free datum, not to the control's frame)"])


def adjust(block: Block | BundleProblem, options: SolveOptions | None = None,
           progress: Progress | None = None) -> BundleResult:
    """Bundle block adjustment of a block as read (prepare, then the one solver; options:
    default the bundle's, bundle_problem.SOLVE)."""
    from baarda.bundle.bundle_problem import BundleProblem

    problem = block if isinstance(block, BundleProblem) else prepare(block)
    return problem.fit(options=options, progress=progress)


def with_variance_components(problem: BundleProblem, progress: Progress | None = None,
                             active=None):
    """(the problem re-weighted with the estimated variance component of every group, the
    estimation): Foerstner's iteration (quality/variance_components.py; weak control axes
    pooled) on the `active` components (default all; a first snooping's survivors keep
    gross errors out of the estimate).  Every component, rejected or not, gets its group's
    factor; `estimation.components()` is what the Assessment's variance_components shows."""
    from baarda.bundle.bundle_model import BundleModel
    from baarda.quality.variance_components import iterate

    start = problem if active is None else problem.reweighted(active, None)
    est = iterate(BundleModel(start.fit(progress=progress)), progress=progress)
    return problem.reweighted(None, est.factors), est


def snoop_with_variance_components(problem: BundleProblem, tests: TestOptions | None = None,
                                   *, max_rounds: int = 10, progress: Progress | None = None,
                                   **snoop_options) -> tuple[Assessment, BundleProblem]:
    """Variance components and snooping in turn (quality.variance_components.alternate): the
    components estimated from every observation, snooping with them, the components again
    without what it rejected, until the rejections no longer change (a gross error inflates
    its group's estimate; an estimate truncated by a snooping with wrong sigmas is too
    small); then each group's largest |w| is tested against the group estimated without it.
    Returns the last snooping (with the variance components) and its re-weighted problem."""
    from baarda.bundle.bundle_model import BundleModel
    from baarda.quality.variance_components import alternate

    tests = tests or TestOptions.resolve(problem.block.settings)
    first = BundleModel(problem.fit(progress=progress))
    qc, est = alternate(first, lambda f: snoop(problem.reweighted(None, f), tests,
                                               progress=progress, **snoop_options),
                        tests=tests, statistic=snoop_options.get("statistic", "w"),
                        max_rounds=max_rounds, progress=progress)
    return (replace(qc, variance_components=est.components()),
            problem.reweighted(None, est.factors))


def assess(result: BundleResult, tests: TestOptions | None = None, *,
           separability: bool = True) -> Assessment:
    """Statistics of every observation (w, tau, r, MDB, external reliability), no rejection;
    separability: the w-test correlations too (False: left None)."""
    from baarda.bundle.bundle_quality import assess as assess_result

    return assess_result(result, tests, separability=separability)


def snoop(block: Block | BundleProblem, tests: TestOptions | None = None, *,
          statistic: str = "w", by_point: bool = False, robust: bool = False,
          max_iterations: int = 200, inseparable: str = "flag",
          progress: Progress | None = None) -> Assessment:
    """Iterative data snooping of a block as read (see bundle/bundle_quality.py);
    `inseparable`: "flag" or "group" (quality/iterative.py)."""
    from baarda.bundle.bundle_problem import BundleProblem
    from baarda.bundle.bundle_quality import snoop as snoop_problem

    problem = block if isinstance(block, BundleProblem) else prepare(block)
    return snoop_problem(problem, tests, statistic=statistic, by_point=by_point,
                         robust=robust, max_iterations=max_iterations,
                         inseparable=inseparable, progress=progress)


def screen_block(block: Block, options: ScreeningOptions | None = None, *,
                 progress: Progress | None = None) -> ScreeningResult:
    """The screening stages (screening/chain.py) on a block as read: in the local frame of
    its CRS, with approximations where it has none (the same block the bundle sees)."""
    from baarda.screening.chain import screen as screen_stages

    return screen_stages(with_approximations(localized(block)), options, progress=progress)


def screen(block: Block, options: ScreeningOptions | None = None, *, snoop: bool = False,
           statistic: str = "w",
           progress: Progress | None = None) -> tuple[ScreeningResult, Assessment]:
    """Screening before the bundle (screening/chain.py), then the bundle adjustment of the
    cleaned block: with `snoop`, data snooping that removes what it rejects together with
    the observations it cannot be told from (the result's block is then the block after
    both), else the statistics of every observation.  The tests (alpha0, beta0,
    alpha_global) are the options' (`ScreeningOptions.tests`), else the project's."""
    from baarda.bundle.bundle_problem import BundleProblem
    from baarda.bundle.bundle_quality import assess as assess_result
    from baarda.screening.chain import screen_and_snoop

    block = with_approximations(localized(block))
    if not block.points.controlled.any():
        raise GeometryError("screening needs control points (stage 3 and the datum of the "
                            "bundle adjustment after it); screen a free network with "
                            "baarda screen --stages 1,2")
    options = options or ScreeningOptions()
    if snoop:
        return screen_and_snoop(block, options, statistic=statistic, progress=progress)
    res = screen_block(block, options, progress=progress)
    result = BundleProblem(res.block).fit(progress=progress)
    return res, assess_result(result, options.resolved_tests(block.settings))


def read_models(path: str | Path, *, covariance: bool = False,
                encoding: str = ENCODING) -> ModelBlock:
    """A model project (models.csv), or any photo block (a project or another program's
    input, read by `read`) formed into stereo models by relative orientation; covariance:
    keep the full covariance of each model point from its relative orientation."""
    from baarda.independent.forming import form_models
    from baarda.io.model_project import read_model_project

    path = Path(path)
    if path.is_dir() and (path / "models.csv").is_file():
        return read_model_project(path, encoding)
    block = with_approximations(localized(read(path, encoding=encoding)))
    return form_models(block, covariance=covariance)


def adjust_models(block: ModelBlock, mode: str = "3d", *, snoop: bool = True,
                  tests: TestOptions | None = None, statistic: str = "w",
                  by_point: bool = False, external: bool | None = None,
                  deformations: tuple[str, ...] | None = ALL_DEFORMATIONS,
                  clusters: dict[str, list[str]] | str | Path | None = None,
                  user: UserHypotheses | str | Path | None = None, level_models: bool = False,
                  vce: bool = False, progress: Progress | None = None) -> BlockQuality:
    """The FOTEF procedure on a model block (independent/workflow.py): pre-adjustment search,
    spatial ('3d') or planimetric + height ('2d') adjustment, data snooping, tests of model
    deformations, control clusters and user hypotheses, external reliability; with `vce`
    the variance components of model XY, model Z, projection centres and control X, Y, Z
    estimated first (with snooping: in turn with it), the tests using the estimated sigmas.
    `clusters` and `user`: the control clusters and user hypotheses, or the paths of their
    files (clusters.csv, hypotheses.csv: io/hypotheses_files.py)."""
    from baarda.independent.workflow import process

    if isinstance(clusters, str | Path):
        from baarda.io.hypotheses_files import read_clusters

        clusters = read_clusters(clusters)
    if isinstance(user, str | Path):
        from baarda.independent.model_hypotheses import UserHypotheses
        from baarda.io.hypotheses_files import read_hypotheses

        user = UserHypotheses(read_hypotheses(user))

    return process(block, mode, do_snoop=snoop, statistic=statistic, by_point=by_point,
                   tests=tests, external=external, deformations=deformations,
                   clusters=clusters, user=user, level_models=level_models, vce=vce,
                   progress=progress)


def online_interpreter(say, *, focal: float | None = None, sigma: float = 10.0,
                       qyy: float | None = None, qtie: float | None = None,
                       tests: TestOptions | None = None, statistic: str = "w",
                       vce: bool = False):
    """The on-line relative orientation with scale transfer, model by model, fed one
    measurement line at a time (relative/online_commands.Interpreter; docs/online.md);
    `say` prints its answers."""
    from baarda.options import DEFAULT_QTIE, DEFAULT_QYY
    from baarda.relative.online_commands import Interpreter

    return Interpreter(say=say, focal=focal, sigma=sigma,
                       qyy=DEFAULT_QYY if qyy is None else qyy,
                       qtie=DEFAULT_QTIE if qtie is None else qtie,
                       tests=tests or TestOptions(), statistic=statistic, vce=vce)


def strip_coordinates_csv(interpreter) -> str:
    """The strip coordinates of an on-line session so far (point, X, Y, Z, model) as CSV;
    '' before the first model is accepted."""
    from baarda.relative.online_commands import coordinates_csv

    session = interpreter.session
    return coordinates_csv(session) if session is not None and session.accepted else ""


def point_pattern(spec: str | Path, *, ties: int = 0, focal: float = 152.0,
                  base: float = 92.0, width: float = 92.0, twin_offset: float = 1.0,
                  qyy: float | None = None, serious: float = 0.8,
                  qtie: float | None = None):
    """(the design, its title) of a point pattern for relative orientation with scale
    transfer (relative/point_pattern.py: Qvv P and the critical transfers): `spec` a named
    or CxR pattern (options.PATTERNS) or a CSV file (io/pattern_file.py)."""
    from baarda.io.pattern_file import read_pattern_points
    from baarda.options import DEFAULT_QTIE, DEFAULT_QYY
    from baarda.relative.point_pattern import PatternPoint, design, standard_pattern

    path = Path(spec)
    if path.suffix.lower() == ".csv" or path.is_file():
        pts = [PatternPoint(*p) for p in read_pattern_points(path)]
        title = f"pattern {path.name}"
    else:
        pts = standard_pattern(str(spec), ties, base, width, twin_offset)
        title = f"pattern {spec}" + (f" with {ties} tie points" if ties else "")
    d = design(pts, focal, base, DEFAULT_QYY if qyy is None else qyy, serious,
               DEFAULT_QTIE if qtie is None else qtie)
    return d, title


def pattern_drawing(design, title: str, svg: bool = False) -> str:
    """A point-pattern design as text (redundancy numbers, serious transfers) or SVG."""
    from baarda.relative.pattern_drawing import svg_drawing, text_drawing

    return svg_drawing(design, title) if svg else text_drawing(design, title)

