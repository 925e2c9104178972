"""`baarda review`: the session, its output folder and the server, run until Ctrl-C or
SIGTERM (docs/review.md)."""

from __future__ import annotations

import errno
import os
import socket
import time
import webbrowser
from pathlib import Path

from baarda.block.photo_block import Block
from baarda.errors import OutputError, ProjectError
from baarda.options import Config
from baarda.review.edits import write_edits
from baarda.review.session import ReviewSession, adjusted

LOCALHOST = ("127.0.0.1", "localhost", "::1")


class OutputLock:
    """A lock beside OUT (.OUT.review.lock, flock: released by the kernel when the process
    dies): a second review of the same OUT while one runs is refused (OutputError)."""

    def __init__(self, out: Path):
        import fcntl

        out = Path(out).resolve()
        out.parent.mkdir(parents=True, exist_ok=True)
        self.path = out.parent / f".{out.name}.review.lock"
        self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o600)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.fd)
            raise OutputError(errno.EBUSY, "another baarda review is writing this folder "
                              "(end it first, or give another -o)", str(out)) from None

    def release(self) -> None:
        import fcntl

        fcntl.flock(self.fd, fcntl.LOCK_UN)
        os.close(self.fd)
        try:
            self.path.unlink()
        except OSError:
            pass


def saver(session: ReviewSession, block: Block, config: Config, out: Path, inputs,
          command: str | None = None):
    """The save of a session: OUT = what `baarda adjust INPUT --edits OUT/edits.csv`
    writes (the same function, review/session.adjusted, from the block as read), with
    edits.csv."""
    from baarda.output.bundle_results import write_results
    from baarda.output.run_folder import RunFolder

    def save() -> dict:
        with session.lock:
            edits = list(session.edits)
        t0 = time.perf_counter()
        state = adjusted(block, config, edits)
        with RunFolder(out, inputs, command=command) as run:
            write_results(run, state.qc)
            write_edits(run.file("edits.csv"), edits)
        session.saved = len(edits)
        return {"out": str(out), "edits": len(edits), "sigma0": float(state.qc.adjustment.sigma0),
                "seconds": round(time.perf_counter() - t0, 3)}
    return save


def resumed(folder: Path) -> tuple[Path, list] | None:
    """A result folder given as INPUT: (the input it was adjusted from, as its summary.json
    names it, and its edits.csv's edits, [] without one); None for a folder that is not a
    result folder.  ProjectError when the input it names is not found from here."""
    import json

    from baarda.review.edits import read_edits

    folder = Path(folder)
    if not ((folder / "summary.json").is_file() and (folder / "run.json").is_file()):
        return None
    try:
        src = json.loads((folder / "summary.json").read_text(encoding="utf-8"))["input"]["path"]
    except (OSError, ValueError, KeyError, TypeError):
        raise ProjectError(str(folder / "summary.json"), "a result folder without the path "
                           "of its input: give the input instead") from None
    path = Path(src)
    if not path.is_absolute() and not path.exists():
        path = folder.parent / src
    if not path.exists():
        raise ProjectError(str(folder / "summary.json"), f"its input {src} is not found "
                           "from here: give the input instead")
    edits = read_edits(folder / "edits.csv") if (folder / "edits.csv").is_file() else []
    return path, edits


def bind(host: str, port: int) -> socket.socket:
    """A listening socket on host:port (0: any free port); OutputError when it cannot."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host, port))
    except OSError as e:
        sock.close()
        raise ProjectError("command line", f"cannot listen on {host}:{port}: {e.strerror}",
                           None, "--port") from None
    sock.listen(64)
    return sock


def serve(session: ReviewSession, token: str, sock: socket.socket, *, folders, pixel_mm,
          save, say, open_browser: bool) -> int:
    """Serve until Ctrl-C or SIGTERM; the first line said is the address with the token.
    Edits not saved are saved when it ends (with an output folder).  Returns the signal
    that ended it (signal.SIGINT or signal.SIGTERM)."""
    import asyncio
    import signal

    from aiohttp import web

    from baarda.review.server import make_app

    host, port = sock.getsockname()[:2]
    shown = f"[{host}]" if ":" in host else host
    hosts = (f"{shown}:{port}", f"localhost:{port}") if host in LOCALHOST else ()
    url = f"http://{shown}:{port}/?token={token}"
    app = make_app(session, token, folders=folders, pixel_mm=pixel_mm, save=save,
                   hosts=hosts)

    async def run() -> int:
        runner = web.AppRunner(app, handle_signals=False, access_log=None)
        await runner.setup()
        try:
            await web.SockSite(runner, sock).start()
            ended: asyncio.Future[int] = asyncio.get_running_loop().create_future()

            def end(sig: int) -> None:
                if not ended.done():
                    ended.set_result(sig)

            for sig in (signal.SIGINT, signal.SIGTERM):
                asyncio.get_running_loop().add_signal_handler(sig, end, int(sig))
            say(f"review: {url}")
            if open_browser:
                webbrowser.open(url)
            return await ended
        finally:
            await runner.cleanup()

    held = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        signum = asyncio.run(run())
    finally:  # the command line's own handlers again (asyncio leaves the defaults)
        for sig, handler in held.items():
            signal.signal(sig, handler)
    session.close()  # the worker of the w-test correlations ends with the server
    if save is not None and session.saved != len(session.edits):
        answer = save()
        say(f"review: {answer['edits']} edit(s) saved to {answer['out']}")
    return signum
