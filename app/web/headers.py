"""Security headers on every answer: pages, fragments, the API, static files and errors.

The HMI loads only its own files: no inline script, style or event handler (templates use
data attributes that static/js/hmi.js handles, and htmx is told not to inject its indicator
style), so the policy forbids everything else, and a script slipped into a page by way of a
model text, a user name or a note does not run.  Framing is refused (click-jacking on a
control page), MIME sniffing too, and referrers leave only within the station.

Nothing the station answers is kept by a browser or a proxy (`Cache-Control: no-store`):
pages, fragments, the API and errors show live station data, names and tokens, and the
back button of a shared terminal after sign-out must not bring them back.  The static files
(`/static`, the same for everyone) are left to the browser's caching, and an answer that set
its own (the icon) keeps it.

No policy allows an inline script or style, nor anything from elsewhere.  The API's
documentation page (/docs, off unless `sp serve --api-docs`) loads the vendored Swagger UI
(app.web.routes.api_docs): its policy differs only in allowing data: images, which Swagger
UI's stylesheet draws its icons with.
"""

from __future__ import annotations

from starlette.types import ASGIApp, Message, Receive, Scope, Send

_COMMON = (
    "object-src 'none'",
    "base-uri 'none'",
    "frame-ancestors 'none'",
    "form-action 'self'",
)
POLICY = "; ".join(
    ("default-src 'self'", "script-src 'self'", "style-src 'self'", "img-src 'self'", *_COMMON)
)
# /docs (only with `sp serve --api-docs`): the vendored Swagger UI, whose stylesheet draws its
# icons as data: images; still only the station's own scripts and styles
DOCS_POLICY = "; ".join(
    (
        "default-src 'self'",
        "script-src 'self'",
        "style-src 'self'",
        "img-src 'self' data:",
        *_COMMON,
    )
)
DOCS_PAGES = frozenset(("/docs",))  # app.web.routes.api_docs

_FIXED = (
    (b"x-frame-options", b"DENY"),
    (b"x-content-type-options", b"nosniff"),
    (b"referrer-policy", b"same-origin"),
)
_NAMES = frozenset((b"content-security-policy", *(name for name, _ in _FIXED)))
_NO_STORE = (b"cache-control", b"no-store")


def headers_for(path: str, docs: bool = False) -> list[tuple[bytes, bytes]]:
    policy = DOCS_POLICY if docs and path in DOCS_PAGES else POLICY
    return [(b"content-security-policy", policy.encode()), *_FIXED]


class SecurityHeaders:
    """Pure ASGI middleware: adds the headers to each response start, replacing any the app
    set; an exception before the response started still answers 500 with them.  `docs`:
    /docs is served (its own policy)."""

    def __init__(self, app: ASGIApp, docs: bool = False) -> None:
        self.app = app
        self.docs = docs

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        added = headers_for(scope["path"], self.docs)
        fresh = not scope["path"].startswith("/static/")
        started = False

        async def send_with_headers(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
                kept = [h for h in message.get("headers", []) if h[0].lower() not in _NAMES]
                if fresh and not any(name.lower() == _NO_STORE[0] for name, _ in kept):
                    kept.append(_NO_STORE)
                message = {**message, "headers": [*kept, *added]}
            await send(message)

        try:
            await self.app(scope, receive, send_with_headers)
        except Exception:
            # Starlette's error middleware sits outside every added one: its 500 would go out
            # bare.  Answer here instead; it sees the response started and only re-raises.
            if not started:
                body = b"Internal Server Error"
                plain = [
                    (b"content-type", b"text/plain; charset=utf-8"),
                    (b"content-length", str(len(body)).encode()),
                ]
                await send_with_headers(
                    {"type": "http.response.start", "status": 500, "headers": plain}
                )
                await send({"type": "http.response.body", "body": body})
            raise
