"""Helpers shared by the commands: exit codes, progress display and -q, test options and the
run folder."""

from __future__ import annotations

import shlex
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from baarda.cli.argtypes import (
    SIGMA_M,
    SIGMA_UM,
    alpha,
    integer,
    number,
    overlap,
    power,
    text_encoding,
)
from baarda.cli.console import console
from baarda.errors import GeometryError, ProjectError
from baarda.options import Requested, TestOptions
from baarda.output.run_folder import RunFolder
from baarda.process import BAD_INPUT as BAD_INPUT
from baarda.process import INTERRUPTED as INTERRUPTED
from baarda.process import NOT_CONVERGED as NOT_CONVERGED
from baarda.process import OK as OK
from baarda.process import TERMINATED as TERMINATED
from baarda.process import WRITE_FAILED as WRITE_FAILED

FOLDER_HELP = ("{}: new, empty, or one that baarda wrote before (the earlier run's files "
               "replaced at the end of the run, other files kept; an interrupted run leaves "
               "it as it was)")



def add_excel_safe_option(p, tables: str = "the result tables") -> None:
    """--excel-safe: text cells a spreadsheet would run as a formula written quoted."""
    p.add_argument("--excel-safe", action="store_true", help=f"write {tables} for "
                   "spreadsheets: a text cell (an id) that begins with =, +, -, @, a tab or "
                   "a carriage return is written as '\"'=...\"' (OWASP's advice against CSV "
                   "formula injection); run.json says so and baarda reads the ids back as "
                   "given (docs/format.md)")


def add_out_argument(p, what: str = "output folder") -> None:
    """The required -o/--out folder of a command that writes a run (output/run_folder.py)."""
    p.add_argument("-o", "--out", type=Path, required=True, help=FOLDER_HELP.format(what))


# exit codes: baarda/process.py (imported here for the commands)
CHECK_FAILED = 5  # baarda check: an invariant of the result folder does not hold
EXIT_CODES = ("exit codes: 0 success, 2 bad input (the message names the file, line and "
              "field, the option and its valid range, or the geometry), 3 not converged "
              "(results written and marked NOT CONVERGED; also data snooping stopped at its "
              "step limit), 4 the results could not be written (the message names the file; "
              "the output folder keeps the earlier run), 5 an invariant of a result folder "
              "does not hold (baarda check), 130 interrupted (Ctrl-C), 143 terminated "
              "(SIGTERM); after 130 and 143 nothing of the run was written.  A standard output "
              "that fails (a closed pipe) is a warning; the commands whose printout is the "
              "result (check, pattern, online, residuals, report --text) then exit 4")


def progress(args):
    """The command's progress display (cli/console.py): a function that shows a message, or
    None (with -q, or when stderr is not a terminal)."""
    return console(args).progress()


def add_quiet_option(p, printout: str = "the printed summary") -> None:
    """-q (counted): -q drops the progress display and the printout on stdout, -qq the
    notes, warnings and the closing verdict line on stderr too (errors are always shown)."""
    p.add_argument("-q", "--quiet", action="count", default=0,
                   help=f"-q: no progress display and no {printout} (notes, warnings and "
                   "the one-line verdict stay on stderr); -qq: only errors")


#: blocks with at least this many photos use the multi-threaded kernels (linalg/parallel.py:
#: the factorisation splits from about 80 photos), so their first run compiles those too
PARALLEL_PHOTOS = 80


def announce_compile(args, photos: int | None = None) -> None:
    """When numerical kernels have yet to be compiled, say so and compile them now in
    parallel processes (linalg/precompile.py; a command calls it once its input is read, with
    the block's number of `photos` when it has one: the multi-threaded kernels are compiled
    too for blocks that will likely use them, the others compile on demand)."""
    from baarda.process import MIN_KERNEL_ADDRESS_SPACE, address_space, memory_limit_text

    if address_space() < MIN_KERNEL_ADDRESS_SPACE:  # LLVM would abort with no message
        raise MemoryError(f"the numerical kernels (numba, LLVM) need at least "
                          f"{MIN_KERNEL_ADDRESS_SPACE / 2**20:.0f} MB of address space; "
                          "below that they end the process without a word: raise the "
                          "limit (ulimit -v)")
    import numba

    from baarda.linalg.precompile import compile_kernels, pending_kernels

    parallel = photos is not None and photos >= PARALLEL_PHOTOS and numba.get_num_threads() > 1
    todo = pending_kernels(parallel)
    if not todo:
        return
    console(args).note("compiling the numerical kernels once (5-20 s, on every CPU; later "
                       "runs start at once)")
    limit = memory_limit_text()
    failed = compile_kernels(parallel=parallel, entries=todo, in_process=not limit)
    if limit and failed:  # compiled on demand, LLVM would abort this process (no message)
        raise MemoryError(f"{len(failed)} numerical kernel(s) could not be compiled under "
                          "this limit (LLVM needs about 1.5 GB): run 'baarda compile' once "
                          "without it, then runs start without compiling")


def add_test_options(p, *, what: str = "the w-test", alpha_global: bool = False,
                     project: bool = True) -> None:
    """--alpha0 and --beta0 (and --alpha-global) of a command, one wording for all: their
    values resolved once over the project's (tests_option).  what: the tests alpha0 is the
    level of; project: the default comes from project.toml (False: no project, the
    defaults of TestOptions)."""
    d = TestOptions()
    where = "project.toml, else " if project else ""
    p.add_argument("--alpha0", type=alpha, help=f"significance level of {what} (default: "
                   f"{where}{d.alpha0:g})")
    p.add_argument("--beta0", type=power, help=f"power of the tests (default: {where}"
                   f"{d.beta0:.2f})")
    if alpha_global:
        p.add_argument("--alpha-global", type=alpha, help="level of the headline global test "
                       "of the variance factor (default: project.toml [tests] alpha_global, "
                       f"else {d.alpha_global:g}; the B-method's coupled test is printed "
                       "beside it)")


def tests_option(settings, args) -> TestOptions:
    """TestOptions from --alpha0/--beta0/--alpha-global over the project's settings (the
    rule of io/configuration.resolve_tests); bad values are input errors."""
    from baarda.io.configuration import resolve_tests

    return resolve_tests(settings, getattr(args, "alpha0", None), getattr(args, "beta0", None),
                         getattr(args, "alpha_global", None))


def requested_settings(args) -> Requested:
    """What a command's options ask for (options.Requested; an option the command does not
    have is not given), resolved over the input's settings by io/configuration.py."""
    def given(name):
        return getattr(args, name, None)

    datum = given("datum")
    if given("free"):
        if datum not in (None, "free"):
            raise ProjectError("command line", f"--free and --datum {datum} contradict")
        datum = "free"
    calibrate = given("calibrate")
    if calibrate is not None and calibrate not in ("all", "none"):
        calibrate = tuple(p.strip() for p in calibrate.split(",") if p.strip())
    return Requested(alpha0=given("alpha0"), beta0=given("beta0"),
                     alpha_global=given("alpha_global"), solver=given("damping"),
                     datum=datum, crs=given("crs"), camera_model=given("camera_model"),
                     calibrate=calibrate, calibration_group=given("calibration_group"),
                     sigma_image_um=given("sigma_image_um"), sigma_px=given("sigma_px"),
                     pixel_mm=given("pixel_mm"))


@contextmanager
def open_run(args, inputs: list[Path]) -> Iterator[RunFolder]:
    """The run folder of `args.out`, checked before any work (output/run_folder.py), as a
    context: committed when the block ends, discarded on an error.  What killed runs left
    beside it is removed and said, and so is an earlier run that could not be removed.  The
    manifest records the command line."""
    argv = getattr(args, "argv", None)
    command = shlex.join(["baarda", *argv]) if argv is not None else None
    con = console(args)
    run = RunFolder(args.out, [p for p in inputs if p is not None], command=command,
                    excel_safe=getattr(args, "excel_safe", False))
    for text in run.cleaned:
        con.warn(text)
    try:
        with run:
            yield run
    finally:
        if run.placed():  # a Ctrl-C from now on comes after the results were written
            con.results_in_place = run.final
    for text in run.warnings:
        con.warn(text)


def add_encoding_option(p) -> None:
    p.add_argument("--encoding", default="utf-8", type=text_encoding,
                   help="text encoding of the input files (e.g. cp1252 or latin-1 for "
                   "files saved by older Windows programs; a UTF-8 byte-order mark is always "
                   "accepted)")


#: the largest simulated or planned block: strips, photos (or models) per strip, and
#: pattern of points per photo (n x n)
MAX_STRIPS, MAX_PHOTOS, MAX_PATTERN = 500, 500, 25


def add_flight_plan_arguments(p, d) -> None:
    """Options of a regular block shared by `simulate` and `plan` (defaults from FlightPlan d)."""
    p.add_argument("--strips", type=integer(1, MAX_STRIPS), default=d.strips,
                   help="number of strips")
    p.add_argument("--photos", type=integer(2, MAX_PHOTOS), default=d.photos_per_strip,
                   help="photos per strip")
    p.add_argument("--forward-overlap", type=overlap, default=d.forward_overlap,
                   help="forward overlap of neighbouring photos (0 <= overlap < 1)")
    p.add_argument("--side-overlap", type=overlap, default=d.side_overlap,
                   help="side overlap of neighbouring strips (0 <= overlap < 1)")
    p.add_argument("--scale", type=number(1, 1e7), default=d.image_scale,
                   help="image scale 1:SCALE")
    p.add_argument("--focal", type=number(1, 1e4, unit="mm"), default=d.focal_mm,
                   help="focal length in mm")
    p.add_argument("--format", type=number(1, 1e4, unit="mm"), default=d.format_mm,
                   help="image format in mm")
    p.add_argument("--pattern", type=integer(2, MAX_PATTERN), default=d.pattern,
                   help="n x n points per photo")
    p.add_argument("--stereo", action="store_true", help="stereo mode (twin rays)")


def add_control_arguments(p, d) -> None:
    """The control layout of a simulated block (`simulate`, `evaluate`; defaults from d)."""
    p.add_argument("--control", default=d.control, choices=["perimeter", "corners", "none"],
                   help="full (XYZ) control: every --control-spacing bases along the border of "
                        "the block, each corner photo measuring one; at the four corners; none")
    p.add_argument("--control-spacing", type=integer(1, MAX_PHOTOS), default=d.control_spacing,
                   help="perimeter control every k base lengths")
    p.add_argument("--height-chains", type=integer(0, MAX_PHOTOS), default=d.height_chains,
                   help="height control chains across the strips every k bases (0: none)")


def add_terrain_and_sigma_arguments(p, d) -> None:
    """Relief and a-priori sigmas of a simulated block (`simulate`, `evaluate`)."""
    p.add_argument("--relief", type=number(-1e4, 1e4, unit="m"), default=d.relief_m,
                   help="terrain relief in m")
    p.add_argument("--sigma-image", type=SIGMA_UM, default=d.sigma_image_um, help="µm")
    p.add_argument("--sigma-control", type=SIGMA_M, nargs=3,
                   default=list(d.sigma_control_m), metavar=("X", "Y", "Z"), help="m")


def feed_lines(interp, lines, name: str, empty: str | None = None) -> None:
    """Measurement lines (a file, stdin) into an on-line interpreter (`baarda online`, with
    or without --bundle): a bad line is an input error naming `name`, its line and its
    field; `empty`: the error when there was no line at all (None: none)."""
    n = 0
    for n, line in enumerate(lines, 1):  # noqa: B007
        if n == 1:
            line = line.removeprefix("\ufeff")  # a UTF-8 byte-order mark
        try:
            interp.feed(line)
        except (GeometryError, ValueError) as e:  # a bad line names its field (column)
            raise ProjectError(name, str(e), n, getattr(e, "column", None)) from None
        if interp.done:
            break
    if n == 0 and empty is not None:
        raise ProjectError(name, empty)
    try:
        interp.finish()
    except ValueError as e:
        raise ProjectError(name, str(e), n, getattr(e, "column", None)) from None


def prompt_lines(interp, banner: str | None, prompt: str, error=None) -> None:
    """Lines typed at a terminal into an on-line interpreter until 'quit' or end of input:
    a bad line is answered (`error(e)`, default 'error: ...') and the session goes on
    ('point> ' while a photo's points are being collected)."""
    if banner is not None:
        print(banner)
    while not interp.done:
        try:
            line = input("point> " if interp.collecting is not None else prompt)
        except EOFError:
            break
        try:
            interp.feed(line)
        except (GeometryError, ValueError) as e:
            if error is not None:
                error(e)
            else:
                print(f"error: {e}")
