"""`baarda convert IN -o OUT [--to FMT]`: any supported input, or a result folder of `baarda
adjust` (its adjusted block), -> a native project folder, or a COLMAP, BAL, OpenSfM,
Bundler, NVM, Metashape, PAT-B or BINGO file (the registry's writers: output/block_formats.py,
sfm_files.py, metashape_files.py, patb_files.py, bingo_files.py; a result folder's rejected
observations go to rejected.csv)."""

from __future__ import annotations

from pathlib import Path

from baarda.cli.common import (
    add_excel_safe_option,
    add_out_argument,
    add_quiet_option,
    open_run,
)
from baarda.cli.console import console
from baarda.cli.inputs import add_input_options, input_paths, read_input
from baarda.errors import ProjectError
from baarda.io.formats import detect, titles
from baarda.output.project_files import write_project
from baarda.output.run_folder import RunFolder
from baarda.output.tables import write_csv
from baarda.pipeline import with_approximations, with_intersected_ties


def register(sub) -> None:
    p = sub.add_parser("convert", help=f"convert {titles()} input (or a project, or a "
                       "result folder) into a native project folder or, with --to, another "
                       "program's files")
    p.add_argument("input", type=Path, help="input file or folder (see docs/formats.md)")
    add_out_argument(p, "project folder to write")
    add_excel_safe_option(p, "the project's tables")
    add_quiet_option(p, "list of what was read and written")
    p.add_argument("--to", choices=TARGETS, default="project",
                   help="what to write: " + ", ".join(f"{t} ({w})" for t, w in
                                                      TARGETS.items()) +
                   "; a result folder of baarda adjust as INPUT gives its adjusted block, "
                   "without the rejected observations (listed in rejected.csv); what a "
                   "format cannot hold is said in notes (docs/formats.md, Writers)")
    add_input_options(p)
    p.set_defaults(func=run_convert)


# what `--to` writes: the target and its files (the help is made of it)
TARGETS = {"project": "a native project folder, the default",
           "colmap": "cameras.txt, images.txt, points3D.txt",
           "bal": "problem.txt",
           "opensfm": "reconstruction.json, tracks.csv, ground_control_points.json",
           "aicon": "block.ior .eor .obc .phc .scale",
           "bundler": "bundle.out, list.txt", "nvm": "model.nvm",
           "metashape": "cameras.xml with bundle.out and list.txt for the tie points",
           "patb": "block.im .con .ori .at .pro",
           "bingo": "block_tp_bingo.txt, block_calibrated_camera_parameters.txt"}
WRITTEN_AS = {"metashape": "metashape-xml"}  # a target whose writer is another format's


def _spec(to: str):
    """The registry entry whose writer writes `to`."""
    from baarda.io.formats import spec

    return spec(WRITTEN_AS.get(to, to))


def _write(block, to: str, folder: Path | RunFolder) -> list[str]:
    """Write `block` as `to` into `folder` (the run itself for a project); the writer's
    notes."""
    if to == "project":
        write_project(block, folder)
        return []
    try:
        return _spec(to).writes(block, folder.path if isinstance(folder, RunFolder) else folder)
    except ValueError as e:
        raise ProjectError(str(block.source or to), f"cannot be written as {to}: {e}") from None


def run_convert(args) -> int:
    from baarda.io.result_block import is_result_folder, read_result_block

    rejected = None
    with open_run(args, input_paths(args)) as run:
        if is_result_folder(args.input):
            fmt = "result folder"
            holds = _spec(args.to).control
            block, rejected = read_result_block(args.input, keep_given=holds)
        else:
            fmt = args.format or detect(args.input)
            block = with_approximations(read_input(args))
            if args.to != "project":  # the other formats store every point's coordinates
                block = with_intersected_ties(block)
        written = _write(block, args.to, run if args.to == "project" else run.path)
        if rejected is not None:
            write_csv(run.file("rejected.csv"), rejected, excel_safe=run.excel_safe)
    con = console(args)
    con.print(f"read {fmt}: {block.summary()}")
    for note in block.notes + written:
        con.note(note)
    con.print(f"{args.to} written to {run.describe()}")
    con.verdict("convert", f"{fmt}: {block.summary()} -> {run.describe()}")
    return 0
