"""The review server: the page and the JSON API over a ReviewSession (docs/review.md).

Every request carries the token (query `token=`, header `X-Baarda-Token` or `Authorization:
Bearer`, or the cookie the page gets on its first load), compared in constant time; without
it 403.  Ids in requests are looked up in the block, never used as paths.  A malformed
request or an edit that cannot apply is a 4xx with {"error": message}; the server keeps
running.  Edits run one at a time in a worker thread (the page stays served meanwhile).
"""

from __future__ import annotations

import asyncio
import hmac
import json
import logging
import secrets
from collections.abc import Sequence
from importlib import resources
from pathlib import Path

from aiohttp import web

from baarda.review.chips import NoImage, chip_png, image_of
from baarda.review.edits import UnknownId
from baarda.review.session import ReviewSession

log = logging.getLogger("baarda.review")
COOKIE = "baarda_review"
STATIC = ("review.js", "review.css")
TYPES = {".js": "text/javascript", ".css": "text/css", ".html": "text/html"}


def new_token() -> str:
    return secrets.token_urlsafe(24)


def _static(name: str) -> bytes:
    return resources.files("baarda.review").joinpath("static", name).read_bytes()


def _error(status: int, message: str) -> web.Response:
    return web.json_response({"error": message}, status=status)


def make_app(session: ReviewSession, token: str, *, folders: Sequence[Path] = (),
             pixel_mm: float | None = None, save=None, hosts: tuple[str, ...] = ()
             ) -> web.Application:
    """The aiohttp application.  folders: where images are looked for (chips.image_folders);
    save: a callable writing OUT (returns a dict for the answer) or None (no -o: 409);
    hosts: the Host header values accepted, or a callable giving them (empty: any; a page of
    another site that resolves to this address is refused: DNS rebinding)."""

    def authorised(request: web.Request) -> bool:
        given = request.query.get("token") or request.headers.get("X-Baarda-Token") or \
            request.cookies.get(COOKIE) or ""
        auth = request.headers.get("Authorization", "")
        if not given and auth.startswith("Bearer "):
            given = auth[7:]
        return hmac.compare_digest(given.encode(), token.encode())

    @web.middleware
    async def guard(request: web.Request, handler):
        allowed = hosts() if callable(hosts) else hosts
        if allowed and request.host not in allowed:
            return _error(403, "unexpected Host header")
        if not authorised(request):
            return _error(403, "a valid token is required (the address review printed)")
        try:
            response = await handler(request)
        except web.HTTPException as e:
            return _error(e.status, e.reason or "error")
        except Exception as e:  # a defect: said, and the server goes on
            log.exception("review: %s %s", request.method, request.path)
            return _error(500, f"internal error: {type(e).__name__}: {e}")
        response.headers.setdefault("Cache-Control", "no-store")
        response.headers["X-Content-Type-Options"] = "nosniff"
        response.headers["Content-Security-Policy"] = (
            "default-src 'self'; img-src 'self' blob: data:; style-src 'self'; "
            "script-src 'self'; object-src 'none'; base-uri 'none'; frame-ancestors 'none'")
        return response

    async def index(request):
        r = web.Response(body=_static("index.html"), content_type="text/html",
                         charset="utf-8")
        r.set_cookie(COOKIE, token, httponly=True, samesite="Strict", path="/")
        return r

    async def static(request):
        name = request.match_info["name"]
        if name not in STATIC:
            return _error(404, "not found")
        return web.Response(body=_static(name), content_type=TYPES[Path(name).suffix],
                            charset="utf-8")

    async def summary(request):
        return web.json_response(session.summary())

    async def observations(request):
        status = request.query.get("status", "flagged")
        if status not in ("flagged", "all"):
            return _error(400, "status: flagged or all")
        rows = await asyncio.to_thread(_locked, session, session.observations, status)
        return web.json_response({"observations": rows})

    async def rays(request):
        point = request.query.get("point", "")
        if point not in session.block.point_index:
            return _error(404, "unknown point")
        rays = _locked(session, session.rays, point)
        for r in rays:  # whether a chip can be asked for (the page asks only then)
            if r["photo"] not in has_image:
                has_image[r["photo"]] = image_of(session.block, list(folders),
                                                   r["photo"]) is not None
            r["image"] = has_image[r["photo"]]
        return web.json_response({"point": point, "rays": rays})

    has_image: dict[str, bool] = {}

    async def block_map(request):
        return web.json_response(_locked(session, session.block_map))

    async def edits(request):
        try:
            body = await request.json()
        except (json.JSONDecodeError, UnicodeDecodeError, ValueError):
            return _error(400, "the body must be JSON")
        try:
            answer = await asyncio.to_thread(session.edit, body)
        except UnknownId as e:
            return _error(404, str(e))
        except ValueError as e:
            return _error(422, str(e))
        return web.json_response(answer)

    async def chip(request):
        photo, point = request.query.get("photo", ""), request.query.get("point", "")
        if photo not in session.block.photos.ids or point not in session.block.point_index:
            return _error(404, "unknown photo or point")
        ray = next((r for r in _locked(session, session.rays, point) if r["photo"] == photo),
                   None)
        if ray is None:
            return _error(404, f"point {point} is not measured on photo {photo}")
        try:
            png, meta = await asyncio.to_thread(chip_png, session.block, list(folders), photo, ray,
                                          pixel_mm)
        except NoImage as e:
            return _error(404, str(e))
        return web.Response(body=png, content_type="image/png", headers={
            "X-Chip-Mm-Per-Px": repr(meta["mm_per_px"]),
            "X-Chip-Mm-Per-Px-Y": repr(meta["mm_per_px_y"]),
            "X-Chip-Centre": f"{meta['cx']!r},{meta['cy']!r}"})

    async def do_save(request):
        if save is None:
            return _error(409, "no output folder: start baarda review with -o OUT")
        try:
            return web.json_response(await asyncio.to_thread(save))
        except (OSError, ValueError) as e:
            return _error(500, f"cannot save: {e}")

    app = web.Application(middlewares=[guard], client_max_size=64 * 1024)
    app.router.add_get("/", index)
    app.router.add_get("/static/{name}", static)
    app.router.add_get("/api/summary", summary)
    app.router.add_get("/api/observations", observations)
    app.router.add_get("/api/rays", rays)
    app.router.add_get("/api/map", block_map)
    app.router.add_post("/api/edits", edits)
    app.router.add_get("/api/chip", chip)
    app.router.add_post("/api/save", do_save)
    return app


def _locked(session: ReviewSession, f, *a):
    with session.lock:
        return f(*a)
