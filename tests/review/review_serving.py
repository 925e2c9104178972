"""A review server of a session in a background thread (port 0), for the tests."""

from __future__ import annotations

import asyncio
import json
import threading
import urllib.error
import urllib.request

from aiohttp import web

from baarda.review.server import make_app


class Served:
    """make_app(session, token, **kw) served on 127.0.0.1:<free port> until close()."""

    def __init__(self, session, token="t0ken-for-tests", **kw):
        self.token = token
        self.loop = asyncio.new_event_loop()
        ready = threading.Event()

        kw.setdefault("hosts", lambda: (f"127.0.0.1:{self.port}", f"localhost:{self.port}"))

        async def start():
            self.runner = web.AppRunner(make_app(session, token, **kw))
            await self.runner.setup()
            site = web.TCPSite(self.runner, "127.0.0.1", 0)
            await site.start()
            self.port = self.runner.addresses[0][1]
            ready.set()

        def run():
            self.loop.run_until_complete(start())
            self.loop.run_forever()

        self.thread = threading.Thread(target=run, daemon=True)
        self.thread.start()
        ready.wait(30)
        self.base = f"http://127.0.0.1:{self.port}"

    def close(self):
        asyncio.run_coroutine_threadsafe(self.runner.cleanup(), self.loop).result(10)
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(10)

    def request(self, path, body=None, token=True, headers=None, raw=None):
        """(status, parsed JSON or bytes, headers) of a request."""
        h = dict(headers or {})
        if token:
            h["X-Baarda-Token"] = self.token
        data = raw if raw is not None else None if body is None else json.dumps(body).encode()
        if data is not None:
            h["Content-Type"] = "application/json"
        req = urllib.request.Request(self.base + path, data=data, headers=h,
                                     method="POST" if data is not None else "GET")
        try:
            with urllib.request.urlopen(req, timeout=60) as r:
                status, payload, hdr = r.status, r.read(), r.headers
        except urllib.error.HTTPError as e:
            status, payload, hdr = e.code, e.read(), e.headers
        if hdr.get("Content-Type", "").startswith("application/json"):
            payload = json.loads(payload)
        return status, payload, hdr
