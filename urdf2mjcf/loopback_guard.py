"""Whom our local servers answer: the user's own pages, and the origins they name.

The browser viewer, the rover console and the Foxglove stream listen on the loopback
interface, but a loopback port is within reach of every web page the user opens: a
page of another site can send requests to it (its own ``fetch``, forms, images,
WebSockets) and, by DNS rebinding (its own name made to resolve to 127.0.0.1), make
them same-origin. :meth:`Guard.check` decides, from a request's own headers, whether
we answer it:

* ``Host`` must be a loopback name (``localhost``, ``127.0.0.1``, ``[::1]``) with our
  port: a rebound name is refused, whatever it resolves to;
* ``Origin``, where a browser sends one (every WebSocket upgrade, every POST), must be
  our own page's or one the user named (``--allow-origin``);
* ``Sec-Fetch-Site``, where a browser sends it, must say the request comes from our
  own page or from the user (an address typed or clicked): an ``<img>`` or
  ``<script>`` of another site sends no ``Origin`` but says ``cross-site`` here;
* with a token (the viewer and the console), the request carries the run's token:
  in the address the command printed (``?token=...``), or in the cookie the answer to
  that address set (``HttpOnly``, ``SameSite=Strict``: a page of another site neither
  reads it nor has it sent).

Nothing here prints; the reasons it gives name no part of the request. A server of
ours to come asks the same :class:`Guard` before it answers anything.
"""

from __future__ import annotations

import hmac
import secrets
import urllib.parse
from collections.abc import Sequence
from dataclasses import dataclass, field
from http.cookies import CookieError, SimpleCookie

import click

LOOPBACK_NAMES = ("localhost", "127.0.0.1", "[::1]")
"""The names a request to us may give in ``Host`` (with our port)."""
TOKEN_PARAM = "token"
"""The query parameter that carries the run's token."""
TOKEN_BYTES = 16
"""Random bytes of a run's token (``secrets.token_urlsafe``)."""
QUERY_FIELDS = 64
"""Fields of a request's query read to find the token, at most (more: no token)."""
ORIGIN_MAX = 256
"""Characters of an ``--allow-origin`` value, at most."""
FOXGLOVE_APP = "https://app.foxglove.dev"
"""The origin of Foxglove's web app: the one to name for the Foxglove stream."""

SECURITY_HEADERS = {
    # what we send is for our own pages only: no other site may embed, frame or sniff it
    "Cross-Origin-Resource-Policy": "same-origin",
    "X-Content-Type-Options": "nosniff",
    "X-Frame-Options": "DENY",
    "Referrer-Policy": "no-referrer",  # the token in the address goes nowhere
}
"""Headers every answer of ours carries."""


@dataclass(frozen=True)
class Refusal:
    """Why a request is not answered: the HTTP status and a reason (no request text)."""

    status: int
    reason: str


def normalize_origin(text: str) -> str:
    """``text`` as a browser writes it in ``Origin`` (``scheme://host[:port]``, lower
    case, no default port); ValueError saying why it is not one."""
    if not isinstance(text, str) or not text or len(text) > ORIGIN_MAX:
        raise ValueError(f"an origin is scheme://host[:port], at most {ORIGIN_MAX} characters")
    if text.strip() == "*":
        raise ValueError("'*' is every site: name the origins to allow, one by one")
    try:
        parts = urllib.parse.urlsplit(text.strip())
        port = parts.port
    except ValueError:
        raise ValueError("not scheme://host[:port]") from None
    scheme, host = parts.scheme.lower(), (parts.hostname or "")
    if scheme not in ("http", "https"):
        raise ValueError("an origin's scheme is http or https")
    if not host or any(c in host for c in "*\\ ") or not host.isascii() or not host.isprintable():
        raise ValueError("an origin names one host (no wildcard)")
    if parts.username is not None or parts.password is not None:
        raise ValueError("an origin has no user name or password")
    if parts.path not in ("", "/") or parts.query or parts.fragment:
        raise ValueError("an origin has no path, query or fragment")
    if ":" in host:
        host = f"[{host}]"
    default = {"http": 80, "https": 443}[scheme]
    return f"{scheme}://{host}" + ("" if port in (None, default) else f":{port}")


class OriginParam(click.ParamType):
    """An ``--allow-origin`` value: one origin, checked and normalized."""

    name = "ORIGIN"

    def convert(
        self, value: object, param: click.Parameter | None, ctx: click.Context | None
    ) -> str:
        try:
            return normalize_origin(str(value))
        except ValueError as exc:
            self.fail(str(exc), param, ctx)


def new_token() -> str:
    """A fresh run's token."""
    return secrets.token_urlsafe(TOKEN_BYTES)


@dataclass(frozen=True)
class Guard:
    """Who one server on ``port`` answers. ``name``: the loopback name in the address
    we print; ``origins``: the other origins the user named; ``token``: the run's token
    (None: none asked, for a server only WebSocket clients reach, whose browsers always
    send ``Origin``)."""

    port: int
    origins: frozenset[str] = frozenset()
    token: str | None = None
    name: str = "localhost"
    hosts: frozenset[str] = field(init=False)
    own: frozenset[str] = field(init=False)

    def __post_init__(self) -> None:
        hosts = frozenset(f"{n}:{self.port}" for n in LOOPBACK_NAMES)
        object.__setattr__(self, "hosts", hosts)
        object.__setattr__(self, "own", frozenset(f"http://{h}" for h in hosts))

    @property
    def cookie(self) -> str:
        """The cookie's name: one per port, as cookies are shared between the ports of a host."""
        return f"urdf2mjcf-{self.port}"

    def url(self, scheme: str = "http", path: str = "/") -> str:
        """The address to print: with the token, where there is one."""
        query = f"?{TOKEN_PARAM}={self.token}" if self.token else ""
        return f"{scheme}://{self.name}:{self.port}{path}{query}"

    def set_cookie(self) -> str:
        """The ``Set-Cookie`` value that lets the page's own later requests in."""
        return f"{self.cookie}={self.token}; Path=/; HttpOnly; SameSite=Strict"

    def token_in(self, target: str) -> bool:
        """Whether the request target's query carries the token."""
        if self.token is None or "?" not in target:
            return False
        try:
            query = urllib.parse.parse_qs(target.split("?", 1)[1], max_num_fields=QUERY_FIELDS)
        except ValueError:  # more fields than any page of ours sends
            return False
        return any(_same(v, self.token) for v in query.get(TOKEN_PARAM, ()))

    def _token_in_cookie(self, cookies: Sequence[str]) -> bool:
        for header in cookies:
            jar: SimpleCookie = SimpleCookie()
            try:
                jar.load(header)
            except CookieError:
                continue
            morsel = jar.get(self.cookie)
            if morsel is not None and self.token is not None and _same(morsel.value, self.token):
                return True
        return False

    def check(
        self,
        target: str,
        host: Sequence[str],
        origin: Sequence[str],
        fetch_site: Sequence[str] = (),
        cookies: Sequence[str] = (),
    ) -> Refusal | None:
        """None where the request is answered, else why not. ``target``: the request's
        path and query; the others: every value of that header the request gave."""
        if len(host) != 1 or host[0].strip().lower() not in self.hosts:
            return Refusal(403, f"this server answers only {self.name}:{self.port}")
        allowed = False
        if origin:
            if len(origin) != 1:
                return Refusal(403, "one Origin, please")
            try:
                seen = normalize_origin(origin[0])
            except ValueError:
                return Refusal(403, "a request from an origin that is not allowed")
            allowed = seen in self.origins
            if seen not in self.own and not allowed:
                return Refusal(
                    403, "a request from an origin that is not allowed (--allow-origin names one)"
                )
        with_token = self.token_in(target)
        sites = {s.strip().lower() for s in fetch_site}
        # A navigation carrying the token is the user's (no other page knows it).
        if sites - {"same-origin", "none"} and not allowed and not with_token:
            return Refusal(403, "a request from another site")
        if self.token is not None and not with_token and not self._token_in_cookie(cookies):
            return Refusal(
                403, "open the address the command printed: it carries this run's token"
            )
        return None


def _same(given: str, token: str) -> bool:
    return hmac.compare_digest(given.encode("utf-8", "replace"), token.encode())
