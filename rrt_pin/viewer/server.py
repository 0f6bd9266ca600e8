"""The thin transport: meshcat's page and websocket served from a thread of this process.

meshcat 0.3.2's own server (``meshcat-server``, ``meshcat.servers.zmqserver``)
is a separate process fed over ZeroMQ; it binds its HTTP port on every
interface whatever host it is given and has no option for the HTTP port.
:class:`ViewerServer` serves the same static files (``meshcat/viewer/dist``,
no CDN) and speaks the same websocket protocol (msgpack-packed commands, the
scene replayed to every browser that connects) from a tornado event loop in a
background thread: it binds only the host asked for (127.0.0.1 by default),
starts no process, and stopping it (``close()``, Ctrl-C, end of
``--serve-for``) leaves nothing behind. Any number of browsers can watch at
once. The page has no authentication.

Against DNS rebinding (a page on ``evil.example`` whose name is made to resolve
to 127.0.0.1), every request — the page, its files and the websocket — must
name in its ``Host`` header a host this server answers to (:func:`allowed_host`):
an IP literal (loopback, the address it listens on, any when it listens on every
interface), ``localhost``, or the ``--host`` name given. Anything else gets 403.
A malformed request (``/static/%00``) gets 400; neither is a traceback: errors of
requests are logged at DEBUG level only.
"""

from __future__ import annotations

import asyncio
import errno
import ipaddress
import logging
import socket
import threading
from typing import Any

from rrt_pin.core.errors import ViewerError
from rrt_pin.viewer._deps import import_meshcat

__all__ = ["DEFAULT_PORT", "PORT_ATTEMPTS", "ViewerServer", "allowed_host", "url_host"]

logger = logging.getLogger("rrt_pin")

#: First port tried when none is given (meshcat's default file-server port).
DEFAULT_PORT = 7000
#: How many consecutive ports are tried from DEFAULT_PORT.
PORT_ATTEMPTS = 100
_TIMEOUT = 30.0


def url_host(host: str) -> str:
    """``host`` as it appears in a URL (IPv6 literals in brackets; all-interfaces as 127.0.0.1)."""
    if host in ("", "0.0.0.0"):
        return "127.0.0.1"
    if host == "::":
        return "[::1]"
    return f"[{host}]" if ":" in host else host


def _split_host(header: str) -> str:
    """The host of a ``Host`` header, without its port or IPv6 brackets, lower-case."""
    header = header.strip().lower()
    if header.startswith("["):  # [::1]:7000
        return header[1 : header.find("]")] if "]" in header else header
    if header.count(":") == 1:  # name:port or a.b.c.d:port
        return header.split(":", 1)[0]
    return header  # a name, an IPv4 literal, or an unbracketed IPv6 literal


def allowed_host(header: str | None, bound: str) -> bool:
    """Whether a request's ``Host`` header names this server (bound to ``bound``).

    IP literals cannot be rebound to another address by DNS: loopback ones, the
    bound address, and any when the server listens on every interface, pass.
    Names pass only when they are ``localhost`` or the name the server was bound
    to (``--host``): a page on any other name is refused, whatever it resolves to.
    """
    if not header:
        return False
    host = _split_host(header)
    bound_host = bound.strip().lower().strip("[]")
    everywhere = bound_host in ("", "0.0.0.0", "::")
    try:
        ip = ipaddress.ip_address(host)
    except ValueError:
        return host in ("localhost", bound_host)
    if ip.is_loopback or everywhere:
        return True
    try:
        return ip == ipaddress.ip_address(bound_host)
    except ValueError:  # bound to a name: its addresses are whatever it resolved to
        try:
            return str(ip) in {a[4][0] for a in socket.getaddrinfo(bound_host, None)}
        except OSError:
            return False


def _bind(host: str, port: int) -> list[socket.socket]:
    from tornado.netutil import bind_sockets

    return bind_sockets(port, address=host or None)


class ViewerServer:
    """meshcat's viewer page, served from a background thread.

    Use as a context manager, or call :meth:`close`. Commands are meshcat
    command objects (``meshcat.commands.SetObject`` …); :meth:`send` applies
    one to the scene tree and forwards it to every connected browser, and a
    browser that connects later gets the whole tree replayed. The object is
    also a meshcat "window": ``meshcat.Visualizer(window=server)`` works.

    Args:
        host: interface to listen on [IP address or name]; 127.0.0.1 by default.
            The page has no authentication: listen elsewhere only on a trusted
            network.
        port: TCP port; None tries DEFAULT_PORT and the next PORT_ATTEMPTS - 1
            ports and takes the first free one; 0 lets the system pick.
            An explicit port that is taken is an error.

    Raises:
        ViewerError: the port is taken (explicit port), no port in the range
            is free, or the host cannot be bound.
    """

    def __init__(
        self, host: str = "127.0.0.1", port: int | None = None, page: str | None = None
    ) -> None:
        import_meshcat()
        self.host = host
        #: The page served at ``/static/`` (:func:`rrt_pin.viewer.page.page_html`), or
        #: None for meshcat's own ``index.html``.
        self.page = page
        self.requested_port = port
        self._sockets = self._bind_sockets(host, port)
        self.port: int = self._sockets[0].getsockname()[1]
        self.web_url = f"http://{url_host(host)}:{self.port}/static/"
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread: threading.Thread | None = None
        self._websockets: set[Any] = set()
        from meshcat.servers.tree import SceneTree

        self._tree = SceneTree()
        self._start()

    # -- binding -----------------------------------------------------------
    @staticmethod
    def _bind_sockets(host: str, port: int | None) -> list[socket.socket]:
        if port is not None:
            if not 0 <= port <= 65535:
                raise ViewerError(f"port {port} is not in 0..65535")
            try:
                return _bind(host, port)
            except OSError as e:
                if e.errno == errno.EADDRINUSE:
                    raise ViewerError(f"port {port} on {host} is already in use") from e
                raise ViewerError(f"cannot listen on {host}:{port}: {e.strerror or e}") from e
        for candidate in range(DEFAULT_PORT, DEFAULT_PORT + PORT_ATTEMPTS):
            try:
                return _bind(host, candidate)
            except OSError as e:
                if e.errno != errno.EADDRINUSE:
                    raise ViewerError(
                        f"cannot listen on {host}:{candidate}: {e.strerror or e}"
                    ) from e
                logger.info("viewer: port %d in use, trying %d", candidate, candidate + 1)
        raise ViewerError(
            f"no free port on {host} in {DEFAULT_PORT}..{DEFAULT_PORT + PORT_ATTEMPTS - 1}"
        )

    @property
    def url(self) -> str:
        """The page's address, e.g. ``http://127.0.0.1:7000/static/``."""
        return self.web_url

    @property
    def moved(self) -> bool:
        """True when no port was asked for and the default one was taken."""
        return self.requested_port is None and self.port != DEFAULT_PORT

    @property
    def n_clients(self) -> int:
        """Number of browsers connected now."""
        return len(self._websockets)

    # -- the event-loop thread ---------------------------------------------
    def _make_app(self) -> Any:
        import os

        import meshcat
        import tornado.web
        import tornado.websocket
        from meshcat.servers.zmqserver import StaticFileHandlerNoCache

        server = self

        class Guarded:
            """Refuses foreign Host headers (403); logs request errors at DEBUG, not as tracebacks."""

            def prepare(self) -> None:
                if not allowed_host(self.request.headers.get("Host"), server.host):
                    logger.debug("viewer: refused Host %r", self.request.headers.get("Host"))
                    raise tornado.web.HTTPError(403)

            def log_exception(self, typ, value, tb) -> None:  # noqa: ANN001
                logger.debug("viewer: %s %s: %s", self.request.method, self.request.uri, value)

        class Page(Guarded, tornado.web.RequestHandler):
            """The page: ours (title, legend, time) when set, else meshcat's index.html."""

            async def get(self) -> None:
                self.set_header("Content-Type", "text/html; charset=UTF-8")
                self.set_header("Cache-Control", "no-store")
                self.write(server.page)

        class Static(Guarded, StaticFileHandlerNoCache):
            def validate_absolute_path(self, root: str, absolute_path: str) -> str | None:
                if "\x00" in absolute_path:
                    raise tornado.web.HTTPError(400)
                return super().validate_absolute_path(root, absolute_path)

            @classmethod
            def get_absolute_path(cls, root: str, path: str) -> str:
                if "\x00" in path:
                    raise tornado.web.HTTPError(400)
                return super().get_absolute_path(root, path)

        class Handler(Guarded, tornado.websocket.WebSocketHandler):
            async def get(self, *args: Any, **kwargs: Any) -> None:
                if self.request.headers.get("Upgrade", "").lower() != "websocket":
                    self.redirect("/static/")
                    return
                await super().get(*args, **kwargs)

            def open(self, *args: str, **kwargs: str) -> None:
                server._websockets.add(self)
                logger.debug("viewer: browser connected (%d)", len(server._websockets))
                server._replay(self)

            def on_message(self, message: str | bytes) -> None:
                pass  # meshcat's page sends only captured images; none are requested

            def on_close(self) -> None:
                server._websockets.discard(self)
                logger.debug("viewer: browser left (%d)", len(server._websockets))

        class NoIcon(Guarded, tornado.web.RequestHandler):
            def get(self) -> None:
                self.set_status(204)

        class NotFound(Guarded, tornado.web.RequestHandler):
            def get(self, *args: Any) -> None:
                raise tornado.web.HTTPError(404)

        def log_request(handler: tornado.web.RequestHandler) -> None:
            r = handler.request
            logger.debug("viewer: %d %s %s", handler.get_status(), r.method, r.uri)

        root = os.path.join(meshcat.viewer_assets_path(), "dist")
        return tornado.web.Application(
            [
                *([(r"/static/", Page), (r"/static/index.html", Page)] if self.page else []),
                (
                    r"/static/(.*)",
                    Static,
                    {"path": root, "default_filename": "index.html"},
                ),
                (r"/favicon.ico", NoIcon),
                (r"/", Handler),
            ],
            log_function=log_request,
            default_handler_class=NotFound,
        )

    def _start(self) -> None:
        self._thread = threading.Thread(target=self._run, name="rrt-pin-viewer", daemon=True)
        self._thread.start()
        if not self._ready.wait(_TIMEOUT):
            self._close_sockets()
            raise ViewerError("viewer server did not start")
        if self._error is not None:
            self._close_sockets()
            raise ViewerError(f"viewer server failed: {self._error}") from self._error

    def _run(self) -> None:
        try:
            asyncio.run(self._main())
        except BaseException as e:  # surfaced to the caller by _start / close
            self._error = e
            self._ready.set()

    async def _main(self) -> None:
        from tornado.httpserver import HTTPServer

        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        http = HTTPServer(self._make_app())
        http.add_sockets(self._sockets)
        self._ready.set()
        try:
            await self._stop.wait()
        finally:
            http.stop()  # closes the listening sockets
            for ws in list(self._websockets):
                ws.close()
            self._websockets.clear()
            await http.close_all_connections()

    def _close_sockets(self) -> None:
        for s in self._sockets:
            try:
                s.close()
            except OSError:
                pass

    # -- commands ------------------------------------------------------------
    def _write(self, ws: Any, data: bytes) -> None:
        from tornado.websocket import WebSocketClosedError

        try:
            future = ws.write_message(data, binary=True)
        except WebSocketClosedError:
            self._websockets.discard(ws)
            return
        # a browser that leaves mid-write is not an error: retrieve and drop it
        future.add_done_callback(lambda f: f.cancelled() or f.exception())

    def _replay(self, ws: Any) -> None:
        from meshcat.servers.tree import walk

        # meshcat's server sends each node's animation with the node; ours go
        # last, so a page that has the animation has every object too.
        animations = []
        for node in walk(self._tree):
            for data in (node.object, *node.properties, node.transform):
                if data is not None:
                    self._write(ws, data)
            if node.animation is not None:
                animations.append(node.animation)
        for data in animations:
            self._write(ws, data)

    def _apply(self, kind: str, path_text: str, data: bytes) -> None:
        from meshcat.servers.tree import SceneTree, find_node

        path = [p for p in path_text.split("/") if p]
        node = find_node(self._tree, path)
        if kind == "set_object" and node.object == data:
            return  # meshcat's cache: the browsers already have it
        for ws in list(self._websockets):
            self._write(ws, data)
        if kind == "set_transform":
            node.transform = data
        elif kind == "set_object":
            node.object = data
            node.properties = []
        elif kind == "set_property":
            node.properties.append(data)
        elif kind == "set_animation":
            node.animation = data
        elif kind == "delete":
            if path:
                parent = find_node(self._tree, path[:-1])
                parent.pop(path[-1], None)
            else:
                self._tree = SceneTree()

    def send(self, command: Any) -> None:
        """Apply one meshcat command (anything with meshcat's ``lower()``) and forward it.

        Blocks until the server thread has applied it, so commands keep their order.
        """
        import umsgpack

        lowered = command.lower()
        kind = lowered["type"]
        if kind not in ("set_object", "set_transform", "set_property", "set_animation", "delete"):
            raise ViewerError(f"unsupported meshcat command {kind!r}")
        data = umsgpack.packb(lowered)
        if self._loop is None or self._thread is None or not self._thread.is_alive():
            raise ViewerError("viewer server is not running")

        async def apply() -> None:
            self._apply(kind, lowered["path"], data)

        asyncio.run_coroutine_threadsafe(apply(), self._loop).result(_TIMEOUT)

    # -- shutting down -------------------------------------------------------
    def close(self) -> None:
        """Stop serving: close the browsers' connections and the listening sockets, end the thread."""
        thread, loop, stop = self._thread, self._loop, self._stop
        if thread is not None and thread.is_alive() and loop is not None and stop is not None:
            try:
                loop.call_soon_threadsafe(stop.set)
            except RuntimeError:  # loop already closed
                pass
            thread.join(_TIMEOUT)
        self._close_sockets()
        self._thread = None

    def __enter__(self) -> ViewerServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
