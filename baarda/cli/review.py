"""`baarda review INPUT [-o OUT] [--port N] [--host H] [--images DIR] [--no-browser]`: the
operator's loop in the browser (review/; docs/review.md)."""

from __future__ import annotations

import shlex
import signal
import sys
from pathlib import Path

from baarda.cli.common import INTERRUPTED, TERMINATED, add_test_options, announce_compile
from baarda.cli.console import console
from baarda.cli.inputs import add_input_options, formats_help, read_configured_input
from baarda.errors import ProjectError


def register(sub) -> None:
    p = sub.add_parser("review", help="review a block in the browser: the suspicious "
                       "observations, their image chips, reject / restore / re-measure / set "
                       "aside, each answered by the test at once")
    p.add_argument("input", type=Path, help=formats_help() + " (docs/formats.md), or a "
                   "result folder of review or adjust: its input with its edits.csv, saved "
                   "back into it unless -o")
    p.add_argument("-o", "--out", type=Path, help="output folder written by Save (and at the "
                   "end): edits.csv and the result folder of `baarda adjust INPUT --edits "
                   "OUT/edits.csv`")
    p.add_argument("--port", type=int, default=0, help="port (default 0: any free port)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default "
                   "127.0.0.1: this computer only; another host is reachable from the "
                   "network, protected by the token only)")
    p.add_argument("--images", type=Path, metavar="DIR", help="folder of the photos' images "
                   "(default: images/ in or beside INPUT)")
    p.add_argument("--no-browser", action="store_true", help="do not open a browser")
    add_test_options(p, alpha_global=True)
    add_input_options(p)
    p.set_defaults(func=run_review)


def run_review(args) -> int:
    from baarda.review.app import OutputLock, bind, resumed, saver, serve
    from baarda.review.chips import image_folders
    from baarda.review.server import new_token
    from baarda.review.session import ReviewSession

    con = console(args)
    earlier = resumed(args.input) if args.input.is_dir() else None
    edits: list = []
    if earlier is not None:  # a result folder: its input, its edits; saved back into it
        if args.out is None:
            args.out = args.input
        args.input, edits = earlier
        con.note(f"reviewing {args.input} with the {len(edits)} edit(s) of {args.out}")
    if not 0 <= args.port <= 65535:
        raise ProjectError("command line", "--port: 0 .. 65535", None, "--port")
    if args.images is not None and not args.images.is_dir():
        raise ProjectError(str(args.images), "--images: not a folder")
    lock = OutputLock(args.out) if args.out is not None else None
    try:
        if args.out is not None:
            from baarda.output.run_folder import check_output_folder

            check_output_folder(args.out, [args.input])
        block, config = read_configured_input(args)
        announce_compile(args, len(block.photos))
        try:
            session = ReviewSession(block, config, edits)
        except ValueError as e:
            if type(e) is not ValueError:
                raise
            raise ProjectError(str(args.input), str(e)) from None
        sock = bind(args.host, args.port)
        if args.host not in ("127.0.0.1", "localhost", "::1"):
            con.warn(f"listening on {args.host}: other computers can reach the review, "
                     "protected by its token only")
        pixel = getattr(args, "pixel_mm", None) or None
        argv = getattr(args, "argv", None)
        save = None
        if args.out is not None:
            command = shlex.join(["baarda", *argv]) if argv is not None else None
            save = saver(session, block, config, args.out, [args.input], command)
        signum = serve(session, new_token(), sock,
                       folders=image_folders(args.input, args.images), pixel_mm=pixel,
                       save=save, open_browser=not args.no_browser,
                       say=lambda s: print(s, flush=True))
    finally:
        if lock is not None:
            lock.release()
    sys.stdout.flush()
    # ended by Ctrl-C or SIGTERM, the edits saved: the exit code of an interrupted command
    return INTERRUPTED if signum == signal.SIGINT else TERMINATED

