"""Command line: a thin layer over the API.  Each command lives in its own module with
`register(subparsers)`; the module list below is the only place that knows them all."""

from __future__ import annotations

import argparse
import importlib
import sys

from baarda.errors import GeometryError, ProjectError
from baarda.output.run_folder import package_version

COMMANDS = [
    "baarda.cli.adjust",
    "baarda.cli.simulate",
    "baarda.cli.online",
    "baarda.cli.pattern",
    "baarda.cli.plan",
    "baarda.cli.report",
    "baarda.cli.residuals",
    "baarda.cli.convert",
    "baarda.cli.models",
    "baarda.cli.screen",
]


class Formatter(argparse.HelpFormatter):
    """Help that shows every option's default unless its text already says it."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        d = action.default
        if ("default" in text or d is None or d is False or d is argparse.SUPPRESS
                or d == [] or action.const is not None and d is True):
            return text
        shown = " ".join(str(v) for v in d) if isinstance(d, (list, tuple)) else str(d)
        return f"{text} (default: {shown.replace('%', '%%')})"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="baarda", description="Quality-controlled aerial triangulation: bundle adjustment, "
        "data snooping and reliability.", epilog="exit codes: 0 success, 2 bad input (the "
        "message names the file, line and field, or the geometry), 3 not converged (results "
        "written and marked NOT CONVERGED), 130 interrupted (nothing written)")
    parser.add_argument("--version", action="version", version=f"baarda {package_version()}")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        importlib.import_module(name).register(sub)
    for p in sub.choices.values():
        p.formatter_class = Formatter
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run one command; the exit code: 0 success, 2 bad input (a message names the file,
    line and field, or the geometry), 3 not converged (results written and marked),
    130 interrupted (nothing half-written is left)."""
    parser = build_parser()
    argv = sys.argv[1:] if argv is None else list(argv)
    args = parser.parse_args(argv)
    args.argv = argv
    try:
        return int(args.func(args) or 0)
    except (ProjectError, GeometryError) as e:
        print(f"baarda: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:  # a file that cannot be read or written (disk full, permissions)
        where = f"{e.filename}: " if e.filename else ""
        print(f"baarda: error: {where}{e.strerror or e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("\nbaarda: interrupted (nothing of this run was written)", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
