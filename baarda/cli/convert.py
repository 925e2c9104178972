"""`baarda convert IN -o PROJECT`: any supported input -> native project folder."""

from __future__ import annotations

from pathlib import Path

from baarda.cli.common import add_out_argument, add_quiet_option, open_run
from baarda.cli.console import console
from baarda.cli.inputs import add_input_options, input_paths, read_input
from baarda.io.formats import detect, titles
from baarda.output.project_files import write_project
from baarda.pipeline import with_approximations


def register(sub) -> None:
    p = sub.add_parser("convert", help=f"convert {titles()} input (or a project) into a "
                       "native project folder")
    p.add_argument("input", type=Path, help="input file or folder (see docs/formats.md)")
    add_out_argument(p, "project folder to write")
    add_quiet_option(p, "list of what was read and written")
    add_input_options(p)
    p.set_defaults(func=run_convert)


def run_convert(args) -> int:
    with open_run(args, input_paths(args)) as run:
        fmt = args.format or detect(args.input)
        block = with_approximations(read_input(args))
        write_project(block, run)
    con = console(args)
    con.print(f"read {fmt}: {block.summary()}")
    for note in block.notes:
        con.note(note)
    con.print(f"project written to {run.describe()}")
    con.verdict("convert", f"{fmt}: {block.summary()} -> {run.describe()}")
    return 0
