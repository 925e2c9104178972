"""Options structs, resolved once where the user's input enters (like COLMAP's options).

`TestOptions` holds the B-method's alpha0 and beta0 of every test; `SolveOptions` the
iteration control of the one solver (baarda/adjustment/solve.py).  Both are frozen: a
function that needs other values gets another instance (`dataclasses.replace`).

`Requested` is what a command line or an API call asks for (None: not given); `Config` the
configuration of one run, merged once from it, the input's settings (project.toml, or what
the source program states) and the defaults by io/configuration.resolve_config (the rule
of each setting is stated there), as COLMAP keeps BundleAdjustmentConfig apart from the
data.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

Progress = Callable[[str], None]  # a progress printer: one line per call


@dataclass(frozen=True)
class TestOptions:
    """Significance level alpha0 of the one-dimensional w-test and power beta0 of every test.

    The B-method (Baarda 1968) couples every other test to these two: delta0 = 4.13 for the
    defaults, and the multi-dimensional tests get the alpha that gives the same power for the
    same non-centrality.
    """

    __test__ = False  # not a pytest class

    alpha0: float = 0.001
    beta0: float = 0.80
    alpha_global: float = 0.05  # level of the headline global test (not the B-method's)

    def __post_init__(self) -> None:
        if not (0.0 < self.alpha0 < 0.5 and 0.5 <= self.beta0 < 1.0):
            raise ValueError(f"alpha0 must be in (0, 0.5) and beta0 in [0.5, 1) (got "
                             f"{self.alpha0}, {self.beta0})")
        if not 0.0 < self.alpha_global < 0.5:
            raise ValueError(f"alpha_global must be in (0, 0.5) (got {self.alpha_global})")

    @classmethod
    def resolve(cls, settings=None, alpha0: float | None = None,
                beta0: float | None = None, alpha_global: float | None = None) -> TestOptions:
        """The user's values where given, else the project's settings, else the defaults."""
        base = cls() if settings is None else cls(
            float(settings.alpha0), float(settings.beta0),
            float(getattr(settings, "alpha_global", cls.alpha_global)))
        return cls(base.alpha0 if alpha0 is None else float(alpha0),
                   base.beta0 if beta0 is None else float(beta0),
                   base.alpha_global if alpha_global is None else float(alpha_global))


@dataclass(frozen=True)
class SolveOptions:
    """Iteration control of the least-squares solver (Gauss-Newton, optionally damped).

    Every problem measures its correction in its own dimensionless units (the bundle:
    positions relative to the flying height, 1000 x angles in rad); see each problem's
    `correction_size`.  The iteration has converged when

    * the correction computed at the current estimate is below `tolerance` (the estimate is
      then the solution, and its factored normal equations serve the statistics), or
    * the last step lowered the weighted sum of squares by less than `flat_cost` (relative)
      and the correction is below `flat_tolerance`, or
    * no step along the correction lowers the sum of squares any more (or the iterations
      are used up) while the correction is below `stall_tolerance` (the rounding floor).

    Steps are halved while they raise the sum of squares by more than `cost_rtol`
    (relative) or leave the admissible region (points behind a camera), down to
    `min_step`.  `damping` (a number): Levenberg-Marquardt with that initial lambda
    (Marquardt's scaling of the diagonal) instead of step halving; the final normal
    equations are always undamped.  `final_step`: at convergence the negligible correction
    is applied as well and the normal equations are factored there (one more factorisation;
    the solution is then accurate to the square of the tolerance).
    """

    max_iterations: int = 50
    tolerance: float = 1e-7
    flat_cost: float = 0.0
    flat_tolerance: float = float("inf")
    stall_tolerance: float = 0.0
    min_step: float = 1e-3
    cost_rtol: float = 1e-12
    damping: float | None = None
    final_step: bool = False

    def __post_init__(self) -> None:
        if self.max_iterations < 1 or self.tolerance < 0 or not 0 < self.min_step <= 1:
            raise ValueError("max_iterations must be >= 1, tolerance >= 0, min_step in (0, 1]")
        if self.damping is not None and not self.damping > 0:
            raise ValueError("damping (Levenberg-Marquardt lambda) must be positive")


DEFAULT_TESTS = TestOptions()

FREE_DATUMS = ("free", "inner")  # a free network (inner: in its inner datum)
DATUMS = ("control", *FREE_DATUMS)
SOLVERS = ("gn", "lm")  # Gauss-Newton with step halving, Levenberg-Marquardt
CALIBRATION_GROUPS = ("camera", "strip")  # the photos that share a camera's parameters


@dataclass(frozen=True)
class ImageOptions:
    """What a reader is given (pixel size [mm], sigma [px] in its pixels) and the sigma
    [µm] set on every observation after reading (None: the reader's own); resolved for the
    input's format by io/image_sigma.resolve_image_options."""

    pixel_mm: float | None = None
    sigma_px: float | None = None
    sigma_um: float | None = None


@dataclass(frozen=True)
class Requested:
    """The settings a command line or an API call gives; None: not given (the input's,
    else the default).  `calibrate`: "all", "none" or the parameter names estimated for
    every camera; `solver`: one of SOLVERS."""

    alpha0: float | None = None
    beta0: float | None = None
    alpha_global: float | None = None
    solver: str | None = None
    datum: str | None = None
    crs: str | None = None
    camera_model: str | None = None
    calibrate: str | tuple[str, ...] | None = None
    calibration_group: str | None = None
    sigma_image_um: float | None = None
    sigma_px: float | None = None
    pixel_mm: float | None = None


@dataclass(frozen=True)
class CalibrationConfig:
    """What a self-calibration estimates: `model` every camera is put on (None: each keeps
    the input's), `free` the parameters estimated per camera of the input (names of
    block/camera.parameter_names; None: none), `group` "camera" (shared by a camera's
    photos) or "strip" (per camera and strip), `source` where `free` comes from."""

    model: str | None = None
    free: tuple[tuple[str, ...], ...] | None = None  # None: nothing estimated
    group: str = "camera"
    source: str = "default"


@dataclass(frozen=True)
class Config:
    """The resolved configuration of one run (io/configuration.resolve_config): the tests,
    the solver (None: the bundle's default), the datum, the CRS, the calibration, the image
    options, and `notes`: how settings given twice were resolved."""

    tests: TestOptions = DEFAULT_TESTS
    solver: str | None = None
    datum: str = "control"
    crs: str | None = None
    calibration: CalibrationConfig = CalibrationConfig()
    image: ImageOptions = ImageOptions()
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class ScreeningOptions:
    """Settings of the screening stages (screening/chain.py): the stages to run, the tests
    of stages 2 and 3 and of the bundle after them (`tests`: alpha0, beta0, alpha_global;
    None: the project's), the photo-pair test of stage 1 and the separability threshold."""

    stages: tuple[int, ...] = (1, 2, 3)
    tests: TestOptions | None = None
    pair_alpha0: float = 1e-4  # stage 1: the 2D model is approximate, so only clear errors
    pair_transform: str = "auto"  # auto | similarity | affine | projective
    pair_statistic: str = "w"  # w (pooled sigma of the pairs) | tau (each pair's own)
    pair_min_redundancy: int = 4
    pair_tolerance_mm: float | None = None  # None: the relief parallax of each pair
    rho_max: float = 0.9  # |correlation| of w-tests above which errors are not separable

    def resolved_tests(self, settings) -> TestOptions:
        """The tests of stages 2 and 3: the options' own, else the project's."""
        return self.tests or TestOptions.resolve(settings)


# relative orientation with scale transfer (relative/orientation.py; Kratky): the cofactor
# of y-parallaxes and of x'' at the tie points relative to q_xx, and the named point
# patterns of his figures (relative/point_pattern.py: name -> columns x rows[+corners])
DEFAULT_QYY = 2.0
DEFAULT_QTIE = 1.0  # see docs/online.md
PATTERNS = {"6": "2x3", "9": "3x3", "10": "2x5", "12": "3x4", "15": "3x5", "13": "3x3+corners"}
