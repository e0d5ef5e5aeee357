"""Serving the app over HTTP (uvicorn), with the limits a station's network needs.

uvicorn alone keeps a connection that never completes a request head for ever: its only timer
is the keep-alive one, armed after a response and cancelled by the first byte of the next
request.  A few hundred silent sockets, or ones that stop half-way through a request line,
would hold the station's file descriptors.  Here a client has `HEAD_TIMEOUT` seconds to send a
complete request head, from connecting and, on a kept-alive connection, from the end of the
previous response; bytes that trickle in do not extend it.  A request body announced by its
head must then arrive within `BODY_TIMEOUT` (a body that never comes held the connection as
well).  Once a request is in, nothing is timed: the server-sent events at /events stream as
long as the page stays open.

Proxy headers are not trusted: by default uvicorn takes the client's address from
X-Forwarded-For on connections from 127.0.0.1, so anyone on the station's own host could pick
an address per attempt and pass the sign-in throttle's per-address limit.
"""

from __future__ import annotations

import asyncio
import contextlib
from typing import ClassVar

import h11
import uvicorn
from starlette.types import ASGIApp
from uvicorn.protocols.http.h11_impl import H11Protocol

HEAD_TIMEOUT = 10.0  # s for a complete request head
BODY_TIMEOUT = 60.0  # s for the body after its head: 8 MiB (a model) at ~140 KB/s
KEEP_ALIVE = 5  # s an idle kept-alive connection stays open (uvicorn's timeout_keep_alive)
STARTUP_FAILURE = 3  # uvicorn.run's exit status when the server cannot start


class HeadDeadlineProtocol(H11Protocol):
    """uvicorn's h11 protocol, closing a connection that waits too long for a request head.

    The deadline runs while h11 waits for a request head (`their_state` is IDLE): armed when
    `connection_made` or `handle_events` leaves it waiting (uvicorn calls the latter after each
    response too, for pipelined requests), cancelled as soon as a head has been parsed.
    """

    timeout: ClassVar[float] = HEAD_TIMEOUT
    body_timeout: ClassVar[float] = BODY_TIMEOUT
    _deadline: asyncio.TimerHandle | None = None
    _timing: object = None  # the h11 state the deadline runs for (IDLE: a head, SEND_BODY)

    def connection_made(self, transport: asyncio.Transport) -> None:  # type: ignore[override]
        super().connection_made(transport)
        self._watch()

    def handle_events(self) -> None:
        super().handle_events()
        self._watch()

    def connection_lost(self, exc: Exception | None) -> None:
        self._cancel()
        super().connection_lost(exc)

    def _watch(self) -> None:
        state = self.conn.their_state
        limits = {h11.IDLE: self.timeout, h11.SEND_BODY: self.body_timeout}
        if state not in limits or self.transport.is_closing():
            self._cancel()
        elif self._deadline is None or self._timing is not state:  # not restarted by a part
            self._cancel()
            self._timing = state
            self._deadline = self.loop.call_later(limits[state], self._expired)

    def _cancel(self) -> None:
        if self._deadline is not None:
            self._deadline.cancel()
            self._deadline = None

    def _expired(self) -> None:
        self._deadline = None
        if not self.transport.is_closing():
            self.transport.close()


def config(
    app: ASGIApp,
    host: str,
    port: int,
    *,
    head_timeout: float = HEAD_TIMEOUT,
    body_timeout: float = BODY_TIMEOUT,
    keep_alive: int = KEEP_ALIVE,
    log_level: str = "warning",
) -> uvicorn.Config:
    """The server's configuration; tests shorten the time-outs to see them work."""
    body_timeout_ = body_timeout

    class Protocol(HeadDeadlineProtocol):
        timeout = head_timeout
        body_timeout = body_timeout_

    return uvicorn.Config(
        app,
        host=host,
        port=port,
        http=Protocol,
        proxy_headers=False,
        timeout_keep_alive=keep_alive,
        log_level=log_level,
    )


def run(app: ASGIApp, host: str, port: int) -> None:
    """Serve until interrupted, as `uvicorn.run` does (exit status 3 if it cannot start,
    e.g. when the port is taken)."""
    server = uvicorn.Server(config(app, host, port))
    with contextlib.suppress(KeyboardInterrupt):  # Ctrl-C, raised again once it is down
        server.run()
    if not server.started:
        raise SystemExit(STARTUP_FAILURE)
