"""`baarda online --bundle PROJECT [-o OUT]` (measurements on stdin, each tested as it is
made) and `baarda online --replay PROJECT -o OUT` (a finished block measured again photo by
photo): the options, and the lines of stdin fed to the interpreter (online/commands.py)."""

from __future__ import annotations

import sys
from pathlib import Path

from baarda.cli.argtypes import positive
from baarda.cli.common import (
    NOT_CONVERGED,
    OK,
    announce_compile,
    feed_lines,
    open_run,
    prompt_lines,
    tests_option,
)
from baarda.cli.inputs import (
    add_input_options,
    input_paths,
    read_configured_input,
    read_input,
)
from baarda.errors import ProjectError

MAX_ROWS = 120  # online/bundle.py MAX_ROWS (not imported: the parser stays light)
RELATIVE_ONLY = ("file", "focal", "tau", "vce")  # options without a default


def add_options(p) -> None:
    g = p.add_argument_group("the growing bundle block (docs/online.md)")
    g.add_argument("--bundle", nargs="?", const="", metavar="PROJECT", help="test every "
                   "measurement of a bundle block as it is made: PROJECT is the block as far "
                   "as it is measured (cameras, photos with approximations, control, image "
                   "points); measurement lines come on stdin (docs/online.md)")
    g.add_argument("--replay", type=Path, metavar="PROJECT", help="measure a finished block "
                   "again photo by photo in strip order, testing each photo as it comes; "
                   "writes replay.csv and the result folder of `baarda adjust PROJECT`")
    g.add_argument("--watch", type=Path, metavar="DIR", help="with --bundle: DIR is a folder "
                   "in which a reconstruction grows (a COLMAP sparse folder rewritten in place, "
                   "or numbered snapshot subfolders DIR/00000001, ...; any input baarda reads): "
                   "each new snapshot's new photos and image points are tested against the "
                   "block before it, observations it dropped taken out; writes watch.csv and "
                   "the result folder of the last state (needs -o OUT; Ctrl-C ends it)")
    g.add_argument("--interval", type=positive("s", 86400.0), default=2.0, metavar="S",
                   help="--watch: seconds between looks at DIR (default 2)")
    g.add_argument("--once", action="store_true", help="--watch: take in every snapshot in "
                   "DIR now, then stop")
    g.add_argument("--json", action="store_true", help="--bundle: answer each line with one "
                   "JSON object (for a program that drives the measuring)")
    g.add_argument("--remove-rejected", action="store_true", help="--replay: take out the "
                   "observation with the largest |w| while one is rejected, or set its point "
                   "aside until its next ray where the test cannot tell its rays apart (as "
                   "an operator who re-measures; the result is then that of the block "
                   "without them)")
    g.add_argument("--refactor-rows", type=int, default=MAX_ROWS, metavar="N", help="factor "
                   "the normal equations again after N added observation components (0: "
                   "after every measurement: every test on the exact solution)")
    g.add_argument("-q", "--quiet", action="store_true", help="--replay: no answers printed")
    add_input_options(g)


def bundle_mode(args) -> bool:
    return args.bundle is not None or args.replay is not None or args.watch is not None


def _checked(args) -> Path:
    """The project of the command; ProjectError for options of the other mode."""
    if args.watch is not None:
        if args.bundle or args.replay is not None:
            raise ProjectError("command line", "--watch DIR is the project: give no "
                               "--bundle PROJECT or --replay with it")
        if args.out is None:
            raise ProjectError("command line", "--watch writes a result folder: give -o OUT")
        out, watched = args.out.resolve(), args.watch.resolve()
        if out == watched or watched in out.parents:
            raise ProjectError(str(args.out), "the output folder is inside the watched "
                               f"folder {args.watch} (it would be read as a snapshot): "
                               "give -o a place outside it")
        if args.remove_rejected:
            raise ProjectError("command line", "--remove-rejected belongs to --replay")
        return args.watch
    if args.once:
        raise ProjectError("command line", "--once belongs to --watch DIR")
    if args.bundle and args.replay is not None:
        raise ProjectError("command line", "--bundle PROJECT and --replay PROJECT: give the "
                           "project once (--bundle --replay PROJECT replays it)")
    project = args.replay if args.replay is not None else args.bundle
    if not project:
        raise ProjectError("command line", "--bundle needs the project: the block as far as "
                           "it is measured (baarda online --bundle PROJECT)")
    used = [o for o in RELATIVE_ONLY if getattr(args, o, None) not in (None, False)]
    if used:
        raise ProjectError("command line", f"--{used[0].replace('_', '-')} belongs to the "
                           "model-by-model relative orientation, not to --bundle / --replay")
    if args.replay is not None and args.out is None:
        raise ProjectError("command line", "--replay writes a result folder: give -o OUT")
    if args.json and args.replay is not None:
        raise ProjectError("command line", "--json answers measurement lines: use it with "
                           "--bundle PROJECT")
    if args.remove_rejected and args.replay is None:
        raise ProjectError("command line", "--remove-rejected belongs to --replay")
    if args.refactor_rows < 0:
        raise ProjectError("command line", "--refactor-rows must be 0 or more", None,
                           "--refactor-rows")
    return Path(project)


def run_bundle(args) -> int:
    args.input = _checked(args)
    if args.out is None:
        return _session(args, None)
    with open_run(args, input_paths(args)) as run:
        code = _session(args, run)
    if not (args.json or args.quiet):
        print(f"results written to {run.describe()}")
    return code


def _session(args, run) -> int:
    if args.watch is not None:
        return _watch(args, run)
    block, config = read_configured_input(args)
    from baarda.online.bundle import refusal

    why = refusal(block)  # before the replay's first step, not at it
    if why:
        raise ProjectError(str(args.input), why)
    tests = config.tests
    announce_compile(args, len(block.photos))
    from baarda.online.replay import tests_table

    if args.replay is not None:
        from baarda.online.replay import replay

        say = None if args.quiet else _brief
        rp = replay(block, tests, remove="worst" if args.remove_rejected else "none",
                    max_rows=args.refactor_rows, progress=say)
        ob, answers, name = rp.online, rp.answers, "replay.csv"
        if not args.quiet:
            print("\n".join(rp.summary_lines()))
    else:
        from baarda.online.bundle import OnlineBundle
        from baarda.online.commands import BundleInterpreter

        try:
            ob = OnlineBundle(block, tests, max_rows=args.refactor_rows)
        except ValueError as e:
            raise ProjectError(str(args.input), str(e)) from None
        interp = BundleInterpreter(ob, print, json=args.json)
        if sys.stdin.isatty():  # a person at the keyboard: a bad line is answered
            _prompt(interp, args.json)
        else:
            feed_lines(interp, sys.stdin, "<stdin>")
        answers, name = interp.answers, "online.csv"
    qc = None
    if ob.started:
        qc = ob.result()
        if not (args.json or args.quiet):
            print(qc.summary())
    elif not args.json:
        print(f"the block could not be adjusted: {ob.status()}")
    if run is not None:
        from baarda.output.online_files import write_online

        write_online(run, qc, tests_table(answers), name)
    return OK if qc is None or qc.adjustment.converged else NOT_CONVERGED


def _watch(args, run) -> int:
    """--watch DIR: the snapshots taken in until DIR holds no new one (--once) or Ctrl-C;
    the result folder of the block as it is then (what is complete)."""
    import argparse

    from baarda.cli.common import INTERRUPTED, TERMINATED
    from baarda.online.watch import Watch

    def reader(path):
        return read_input(argparse.Namespace(**{**vars(args), "input": path}))

    def say(name, a):
        if args.json:
            print(a.json(), flush=True)
        elif not args.quiet:
            print(f"[{name}] ", end="")
            _brief(a)

    w = Watch(args.watch, lambda settings: tests_option(settings, args), reader,
              max_rows=args.refactor_rows, progress=say)
    stopped = None
    try:
        w.run(args.interval, args.once)
    except KeyboardInterrupt as e:  # Ctrl-C (or SIGTERM): what is complete is written
        stopped = e
    ob = w.online
    qc = ob.result() if ob is not None and ob.started else None
    if not (args.json or args.quiet):
        print("\n".join(w.summary_lines()))
        if qc is not None:
            print(qc.summary())
    from baarda.output.online_files import write_online

    write_online(run, qc, w.table(), "watch.csv")
    if stopped is not None:
        from baarda.cli import Terminated

        return TERMINATED if isinstance(stopped, Terminated) else INTERRUPTED
    return OK if qc is None or qc.adjustment.converged else NOT_CONVERGED


def _brief(a) -> None:
    """One line per replayed step; the whole answer where something was rejected."""
    if a.verdict == "reject" or any(c.after == "reject" for c in a.changed):
        print(a.text())
    else:
        print(f"STEP {a.step}: {a.what}: {len(a.tested)} tested, {a.verdict}"
              + (f", {len(a.changed)} verdict(s) changed" if a.changed else ""))


def _prompt(interp, json_mode: bool = False) -> None:
    """Lines typed at the prompt: a bad line is answered (with --json as {"error": ...,
    "field": ...}) and the session goes on."""
    import json

    def error(e) -> None:
        print(json.dumps({"error": str(e), "field": getattr(e, "column", None)}), flush=True)

    if json_mode:
        prompt_lines(interp, None, "", error)
    else:
        prompt_lines(interp, "baarda online --bundle: type 'help' for the commands, 'quit' "
                     "to stop", "bundle> ")
    if interp.collecting is not None:
        print(f"photo {interp.collecting[0]} was not closed with 'end': its points are "
              "left out")
