"""Helpers shared by the commands: progress display, test options and the run folder."""

from __future__ import annotations

import shlex
import sys
import time
from pathlib import Path

from baarda.errors import ProjectError
from baarda.options import TestOptions
from baarda.output.run_folder import RunFolder

FOLDER_HELP = ("{}: new, empty, or one that baarda wrote before (replaced whole at the end "
               "of the run; an interrupted run leaves it as it was)")



def add_out_argument(p, what: str = "output folder") -> None:
    """The required -o/--out folder of a command that writes a run (output/run_folder.py)."""
    p.add_argument("-o", "--out", type=Path, required=True, help=FOLDER_HELP.format(what))


# exit codes (the parser's epilog)
OK, BAD_INPUT, NOT_CONVERGED, INTERRUPTED = 0, 2, 3, 130
CHECK_FAILED = 5  # baarda check: an invariant of the result folder does not hold


def progress(quiet: bool):
    """A progress printer to stderr with elapsed time, or None when quiet."""
    if quiet:
        return None
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:7.1f} s] {msg}", file=sys.stderr, flush=True)

    return say


#: blocks with at least this many photos use the multi-threaded kernels (linalg/parallel.py:
#: the factorisation splits from about 80 photos), so their first run compiles those too
PARALLEL_PHOTOS = 80


def announce_compile(say, photos: int | None = None) -> None:
    """When numerical kernels have yet to be compiled, say so and compile them now in
    parallel processes (linalg/precompile.py; a command calls it once its input is read, with
    the block's number of `photos` when it has one: the multi-threaded kernels are compiled
    too for blocks that will likely use them, the others compile on demand)."""
    import numba

    from baarda.linalg.precompile import compile_kernels, pending_kernels

    parallel = photos is not None and photos >= PARALLEL_PHOTOS and numba.get_num_threads() > 1
    todo = pending_kernels(parallel)
    if not todo:
        return
    if say is not None:
        say("compiling the numerical kernels once (5-20 s, on every CPU; later runs start at "
            "once)")
    compile_kernels(parallel=parallel, entries=todo)


def add_test_options(p, *, what: str = "the w-test", alpha_global: bool = False,
                     project: bool = True) -> None:
    """--alpha0 and --beta0 (and --alpha-global) of a command, one wording for all: their
    values resolved once over the project's (tests_option).  what: the tests alpha0 is the
    level of; project: the default comes from project.toml (False: no project, the
    defaults of TestOptions)."""
    d = TestOptions()
    where = "project.toml, else " if project else ""
    p.add_argument("--alpha0", type=float, help=f"significance level of {what} (default: "
                   f"{where}{d.alpha0:g})")
    p.add_argument("--beta0", type=float, help=f"power of the tests (default: {where}"
                   f"{d.beta0:.2f})")
    if alpha_global:
        p.add_argument("--alpha-global", type=float, help="level of the headline global test "
                       "of the variance factor (default: project.toml [tests] alpha_global, "
                       f"else {d.alpha_global:g}; the B-method's coupled test is printed "
                       "beside it)")


def tests_option(settings, args) -> TestOptions:
    """TestOptions from --alpha0/--beta0 over the project's settings; bad values are input
    errors."""
    try:
        return TestOptions.resolve(settings, getattr(args, "alpha0", None),
                                   getattr(args, "beta0", None),
                                   getattr(args, "alpha_global", None))
    except ValueError as e:
        raise ProjectError("command line", str(e)) from None


def open_run(args, inputs: list[Path]) -> RunFolder:
    """The run folder of `args.out`, checked before any work (output/run_folder.py); the
    manifest records the command line."""
    argv = getattr(args, "argv", None)
    command = shlex.join(["baarda", *argv]) if argv is not None else None
    return RunFolder(args.out, [p for p in inputs if p is not None], command=command)


def add_encoding_option(p) -> None:
    p.add_argument("--encoding", default="utf-8", help="text encoding of the input files "
                   "(e.g. cp1252 or latin-1 for files saved by older Windows programs; a "
                   "UTF-8 byte-order mark is always accepted)")


def add_flight_plan_arguments(p, d) -> None:
    """Options of a regular block shared by `simulate` and `plan` (defaults from FlightPlan d)."""
    p.add_argument("--strips", type=int, default=d.strips, help="number of strips")
    p.add_argument("--photos", type=int, default=d.photos_per_strip, help="photos per strip")
    p.add_argument("--forward-overlap", type=float, default=d.forward_overlap,
                   help="forward overlap of neighbouring photos (0..1)")
    p.add_argument("--side-overlap", type=float, default=d.side_overlap,
                   help="side overlap of neighbouring strips (0..1)")
    p.add_argument("--scale", type=float, default=d.image_scale, help="image scale 1:SCALE")
    p.add_argument("--focal", type=float, default=d.focal_mm, help="focal length in mm")
    p.add_argument("--format", type=float, default=d.format_mm, help="image format in mm")
    p.add_argument("--pattern", type=int, default=d.pattern, help="n x n points per photo")
    p.add_argument("--stereo", action="store_true", help="stereo mode (twin rays)")


def add_control_arguments(p, d) -> None:
    """The control layout of a simulated block (`simulate`, `evaluate`; defaults from d)."""
    p.add_argument("--control", default=d.control, choices=["perimeter", "corners", "none"],
                   help="full (XYZ) control: every --control-spacing bases along the border of "
                        "the block, each corner photo measuring one; at the four corners; none")
    p.add_argument("--control-spacing", type=int, default=d.control_spacing,
                   help="perimeter control every k base lengths")
    p.add_argument("--height-chains", type=int, default=d.height_chains,
                   help="height control chains across the strips every k bases (0: none)")


def add_terrain_and_sigma_arguments(p, d) -> None:
    """Relief and a-priori sigmas of a simulated block (`simulate`, `evaluate`)."""
    p.add_argument("--relief", type=float, default=d.relief_m, help="terrain relief in m")
    p.add_argument("--sigma-image", type=float, default=d.sigma_image_um, help="µm")
    p.add_argument("--sigma-control", type=float, nargs=3, default=list(d.sigma_control_m),
                   metavar=("X", "Y", "Z"), help="m")
