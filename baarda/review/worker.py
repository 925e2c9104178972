"""The w-test correlations of a review's states, computed in a process of their own
(docs/review.md).

In a thread of the server their kernels, which hold the interpreter lock, held up the next
edit by seconds on a block of 1,000 photos; in a process of the lowest priority they do
not.  The process is spawned (a forked copy of OpenMP's threads can hang) on the first
request and given the block as read; each request is the list of edits, answered by the
correlations of the block with them as `baarda adjust --edits` computes them.  A request
that a newer one overtook while it waited is skipped.  `close` ends the process (a
computation under way is dropped); it is a daemon, so it never outlives the server.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

from baarda.block.photo_block import Block
from baarda.options import Config

Answer = Callable[[int, Any], None]  # (request number, (rho_max, rho_partner, msb) or None)


class SeparabilityWorker:
    """Requests numbered 1, 2, ...; `answer(n, result)` is called from a thread of this
    process when request n is answered (result None: the process failed)."""

    def __init__(self, block: Block, config: Config, answer: Answer):
        self.block, self.config, self.answer = block, config, answer
        self.lock = threading.Lock()
        self.sent = 0
        self.done = 0  # the last request answered (or given up: the process ended)
        self.changed = threading.Condition(self.lock)
        self.proc: Any = None
        self.conn: Any = None

    def request(self, edits: list) -> int:
        """Send a request (starting the process the first time); its number."""
        with self.lock:
            if self.proc is None:
                self._start()
            self.sent += 1
            n = self.sent
            try:
                self.conn.send((n, list(edits)))
            except (OSError, ValueError):  # the process has ended
                self.done = n
                self.changed.notify_all()
            return n

    def wait(self, n: int, timeout: float | None = None) -> bool:
        """Wait until request n is answered; whether it was."""
        with self.lock:
            return self.changed.wait_for(lambda: self.done >= n, timeout)

    def close(self) -> None:
        with self.lock:
            proc, self.proc = self.proc, None
            conn, self.conn = self.conn, None
            self.done = self.sent
            self.changed.notify_all()
        if proc is not None:
            proc.terminate()
            proc.join(5)
            conn.close()

    def _start(self) -> None:
        from multiprocessing import get_context

        ctx = get_context("spawn")
        here, there = ctx.Pipe()
        self.proc = ctx.Process(target=_serve, args=(there, self.block, self.config),
                                daemon=True, name="baarda review: w-test correlations")
        self.proc.start()
        there.close()
        self.conn = here
        threading.Thread(target=self._listen, args=(here,), daemon=True).start()

    def _listen(self, conn) -> None:
        while True:
            try:
                n, result = conn.recv()
            except (EOFError, OSError):
                with self.lock:
                    if self.conn is conn:  # the process died: nothing more will come
                        self.done = self.sent
                        self.changed.notify_all()
                return
            self.answer(n, result)
            with self.lock:
                self.done = max(self.done, n)
                self.changed.notify_all()


def _serve(conn, block: Block, config: Config) -> None:
    """The worker process: answer requests, the newest first, until the pipe closes."""
    import os

    from baarda.review.session import adjusted

    try:
        os.nice(19)
    except OSError:
        pass
    while True:
        try:
            n, edits = conn.recv()
            while conn.poll():  # overtaken: only the newest is wanted
                n, edits = conn.recv()
        except (EOFError, OSError):
            return
        try:
            q = adjusted(block, config, edits).qc.quality
            result: Any = (q.rho_max, q.rho_partner, q.msb)
        except Exception:  # noqa: BLE001  (the server computes them itself then)
            result = None
        try:
            conn.send((n, result))
        except (OSError, ValueError):
            return
