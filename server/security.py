"""Access control and request hygiene for the knowledge-base service.

Off by default, so a laptop user needs nothing: with no token configured every route is open.
Once a token is set (`CPKB_TOKEN`, or `CPKB_TOKENS_FILE` with one token per line), every write
and delete needs `Authorization: Bearer <token>` (401 without); reads stay open unless
`CPKB_AUTH_READS` is true. Classification is deny-by-default: a route is a read only if its
method is GET/HEAD/OPTIONS or it is one of the POST queries below that store nothing, so a
new write route is protected without anyone remembering to mark it. (`/suggest` records its
answer as pending only for a caller that `may_write`, so an open read changes nothing.)

Browsers cannot send a bearer header when they open a page, so the dashboard's reads (when
`CPKB_AUTH_READS` guards them) accept the token from an HttpOnly, SameSite=Strict cookie set by
`/login`; writes never accept the cookie, so a cross-site form cannot write with it.

Wiring (two lines in the app factory; the dependency only documents the header):
    app = FastAPI(..., dependencies=[Depends(bearer_scheme)])
    install_security(app, settings)
"""

from __future__ import annotations

import hmac
import html
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Protocol
from urllib.parse import parse_qs, quote

from fastapi import APIRouter, FastAPI, Query, Request, Response, status
from fastapi.middleware.cors import CORSMiddleware
from fastapi.responses import HTMLResponse, JSONResponse, RedirectResponse
from fastapi.security import HTTPBearer
from pydantic import SecretStr
from starlette.routing import Match
from starlette.types import ASGIApp, Message, Receive, Scope, Send

READ_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
# POST routes that only query: they take a body because their question does not fit a URL.
READ_ONLY_POST_SUFFIXES = ("/types/match", "/predict", "/suggest")
# Always open, so that liveness probes and the API docs work without a token.
DOCS_ASSETS = "/docs/assets"
OPEN_PATHS = frozenset(
    {"/healthz", "/docs", "/redoc", "/openapi.json", DOCS_ASSETS, "/login", "/logout"}
)
COOKIE = "cpkb_token"


class SecurityConfigError(ValueError):
    """The access settings cannot be honoured (say, a tokens file that cannot be read)."""


class AccessSettings(Protocol):
    """The fields of `server.settings.Settings` this module reads."""

    token: SecretStr | None
    tokens_file: Path | None
    auth_reads: bool
    cors_origins: list[str]
    max_body_bytes: int


def read_tokens_file(path: Path) -> list[str]:
    """Tokens from a file: one per line, blank lines and `#` comments ignored.

    An unreadable or empty file is an error at start-up: failing open would silently
    publish a knowledge base that its owner meant to protect.
    """
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SecurityConfigError(f"cannot read tokens file {path}: {exc.strerror}") from exc
    tokens = [line.strip() for line in text.splitlines()]
    tokens = [t for t in tokens if t and not t.startswith("#")]
    if not tokens:
        raise SecurityConfigError(f"tokens file {path} holds no token")
    return tokens


@dataclass(frozen=True)
class AccessPolicy:
    """Which tokens are valid and whether reads need one; no tokens means open."""

    tokens: tuple[bytes, ...] = ()
    guard_reads: bool = False

    @classmethod
    def from_tokens(cls, tokens: Iterable[str], guard_reads: bool = False) -> AccessPolicy:
        cleaned = tuple(t.strip().encode("utf-8") for t in tokens if t and t.strip())
        return cls(tokens=cleaned, guard_reads=guard_reads)

    @classmethod
    def from_settings(cls, settings: AccessSettings) -> AccessPolicy:
        tokens: list[str] = []
        if settings.token is not None and settings.token.get_secret_value().strip():
            tokens.append(settings.token.get_secret_value())
        if settings.tokens_file is not None:
            tokens.extend(read_tokens_file(settings.tokens_file))
        return cls.from_tokens(tokens, guard_reads=settings.auth_reads)

    @property
    def enabled(self) -> bool:
        return bool(self.tokens)

    def accepts(self, presented: str | None) -> bool:
        """Constant-time check of a presented token against every configured one.

        Every configured token is compared (no early exit), so timing reveals neither
        which token matched nor how long a matching prefix was.
        """
        if presented is None:
            return False
        candidate = presented.encode("utf-8")
        matched = False
        for token in self.tokens:
            matched |= hmac.compare_digest(candidate, token)
        return matched

    def needs_token(self, method: str, route_path: str) -> bool:
        if not self.enabled or route_path in OPEN_PATHS:
            return False
        return self.guard_reads or is_write(method, route_path)


def is_write(method: str, route_path: str) -> bool:
    """Deny by default: anything but a read method or a known query POST is a write."""
    method = method.upper()
    if method in READ_METHODS:
        return False
    return not (method == "POST" and route_path.endswith(READ_ONLY_POST_SUFFIXES))


bearer_scheme = HTTPBearer(
    auto_error=False,
    description="Needed for writes and deletes when the server has a token (CPKB_TOKEN).",
)
"""Declares the bearer header in the API docs; `AccessGate` checks it."""

NEEDS_TOKEN = (
    "this server needs a token: send 'Authorization: Bearer <token>' "
    "(client: token=..., CLI: --token or CPKB_TOKEN; browser: /login)"
)


def _route_path(scope: Scope) -> str:
    """The template of the route `scope` goes to (`/v1/kbs/{kb}/points`), else its path."""
    for route in getattr(scope.get("app"), "routes", ()):
        match, _ = route.matches(scope)
        if match is Match.FULL:
            return str(getattr(route, "path", scope["path"]))
    return str(scope["path"])


def _bearer_token(request: Request) -> str | None:
    scheme, _, token = request.headers.get("authorization", "").partition(" ")
    return token.strip() or None if scheme.lower() == "bearer" else None


def refusal(policy: AccessPolicy, request: Request, route_path: str) -> Response | None:
    """The answer to a request this route needs a token for and that has none valid: 401, or
    for a browser opening a page, a redirect to /login. None when the request may pass."""
    if not policy.needs_token(request.method, route_path):
        return None
    presented = _bearer_token(request)
    if presented is None and not is_write(request.method, route_path):
        presented = request.cookies.get(COOKIE)
    if presented is None:
        if request.method == "GET" and "text/html" in request.headers.get("accept", ""):
            target = quote(request.url.path, safe="/")
            return RedirectResponse(f"/login?next={target}", status.HTTP_303_SEE_OTHER)
        return JSONResponse(
            {"detail": NEEDS_TOKEN}, status.HTTP_401_UNAUTHORIZED, {"WWW-Authenticate": "Bearer"}
        )
    if not policy.accepts(presented):
        return JSONResponse(
            {"detail": "invalid token"},
            status.HTTP_401_UNAUTHORIZED,
            {"WWW-Authenticate": 'Bearer error="invalid_token"'},
        )
    return None


def may_write(request: Request) -> bool:
    """Whether the caller may write: the service has no token, or the request's bearer token
    is valid (the dashboard's cookie grants reads only)."""
    policy: AccessPolicy = getattr(request.app.state, "access_policy", None) or AccessPolicy()
    return not policy.enabled or policy.accepts(_bearer_token(request))


class AccessGate:
    """ASGI middleware: a request without the token its route needs is answered before
    anything reads its body, so unauthenticated uploads cost the server no memory."""

    def __init__(self, app: ASGIApp, policy: AccessPolicy) -> None:
        self.app = app
        self.policy = policy

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http" and self.policy.enabled:
            answer = refusal(self.policy, Request(scope), _route_path(scope))
            if answer is not None:
                await answer(scope, receive, send)
                return
        await self.app(scope, receive, send)


login_router = APIRouter(include_in_schema=False)


def _local_path(target: str) -> str:
    """Only same-site paths after a login: no open redirect to another host."""
    return target if target.startswith("/") and not target.startswith("//") else "/"


# Inline, not the dashboard's stylesheet: when reads need a token, that file needs one too.
LOGIN_STYLE = (
    ":root{color-scheme:light dark;--ink:#111827;--muted:#6b7280;--line:#e5e7eb;"
    "--page:#f9fafb;--panel:#fff;--accent:#2563eb;--bad:#b91c1c}"
    "@media (prefers-color-scheme:dark){:root{--ink:#e5e7eb;--muted:#9ca3af;--line:#374151;"
    "--page:#0b1120;--panel:#111827;--accent:#93c5fd;--bad:#f87171}}"
    "body{margin:0;font:14px/1.45 system-ui,sans-serif;color:var(--ink);"
    "background:var(--page);display:grid;place-items:center;min-height:100vh}"
    "main{background:var(--panel);border:1px solid var(--line);border-radius:8px;"
    "padding:1.5rem 2rem;width:min(24rem,92vw)}h1{font-size:1.2rem;margin:0 0 1rem}"
    "form{display:flex;flex-direction:column;gap:.8rem}label{display:flex;flex-direction:column;"
    "gap:.3rem;color:var(--muted)}input,button{font:inherit;color:var(--ink);padding:.4rem .5rem;"
    "border:1px solid var(--line);border-radius:4px;background:var(--page)}"
    "button{background:var(--accent);color:var(--panel);border:0;cursor:pointer}"
    "[role=alert]{color:var(--bad);margin:0 0 .8rem}"
)


def _login_page(target: str, error: str = "") -> str:
    message = f"<p role=alert>{html.escape(error)}</p>" if error else ""
    return (
        "<!doctype html><html lang=en><meta charset=utf-8>"
        "<meta name=viewport content='width=device-width, initial-scale=1'>"
        f"<title>cpkb: sign in</title><style>{LOGIN_STYLE}</style>"
        "<main><h1>cpkb knowledge base</h1>"
        f"{message}<form method=post action=/login>"
        f"<input type=hidden name=next value='{html.escape(_local_path(target), quote=True)}'>"
        "<label>Token <input type=password name=token autofocus></label>"
        "<button>Sign in</button></form></main>"
    )


@login_router.get("/login", response_class=HTMLResponse)
def login_form(target: Annotated[str, Query(alias="next", max_length=2000)] = "/") -> str:
    return _login_page(target)


# The login form's body: a token and a target path; anything longer is not a login.
LOGIN_MAX_BYTES = 16 * 1024
LOGIN_MAX_FIELDS = 4


@login_router.post("/login", response_class=HTMLResponse)
async def login(request: Request) -> Response:
    """Check the token from the form; on success keep it in a cookie that only reads accept.
    A server without a token needs no cookie and sets none."""
    body = await request.body()
    if len(body) > LOGIN_MAX_BYTES:
        return _form_refusal(413, f"the login form is over {LOGIN_MAX_BYTES} bytes")
    try:
        fields = parse_qs(body.decode("utf-8", "replace"), max_num_fields=LOGIN_MAX_FIELDS)
    except ValueError:
        return _form_refusal(400, f"the login form has more than {LOGIN_MAX_FIELDS} fields")
    token = fields.get("token", [""])[0]
    target = _local_path(fields.get("next", ["/"])[0])
    policy: AccessPolicy = getattr(request.app.state, "access_policy", None) or AccessPolicy()
    if policy.enabled and not policy.accepts(token):
        return HTMLResponse(_login_page(target, "invalid token"), status_code=401)
    response = RedirectResponse(target, status_code=status.HTTP_303_SEE_OTHER)
    if policy.enabled:
        if not _cookie_safe(token):
            return _form_refusal(400, "this token cannot be kept in a cookie: send it as a header")
        response.set_cookie(COOKIE, token, httponly=True, samesite="strict", path="/")
    return response


def _cookie_safe(token: str) -> bool:
    """Printable ASCII without the characters a cookie value cannot hold."""
    return token.isascii() and token.isprintable() and not any(c in token for c in ' ",;\\')


def _form_refusal(code: int, detail: str) -> Response:
    return HTMLResponse(f"<!doctype html><p role=alert>{html.escape(detail)}</p>", code)


@login_router.post("/logout")
def logout() -> Response:
    response = RedirectResponse("/login", status_code=status.HTTP_303_SEE_OTHER)
    response.delete_cookie(COOKIE, path="/")
    return response


class BodySizeLimit:
    """ASGI middleware: a body over `max_bytes` gets a 413 before anyone parses it.

    Checks the declared Content-Length first, then reads the body itself up to the limit
    (a chunked upload declares no length), and replays it to the app once it is within bounds.
    """

    def __init__(self, app: ASGIApp, max_bytes: int) -> None:
        self.app = app
        self.max_bytes = max_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        declared = dict(scope.get("headers") or []).get(b"content-length")
        if declared is not None and declared.isdigit() and int(declared) > self.max_bytes:
            await self._reject(send)
            return
        chunks: list[bytes] = []
        received = 0
        while True:
            message = await receive()
            if message["type"] != "http.request":
                await self.app(scope, _replay([message]), send)
                return
            chunk = message.get("body", b"")
            received += len(chunk)
            if received > self.max_bytes:
                await self._reject(send)
                return
            chunks.append(chunk)
            if not message.get("more_body", False):
                break
        body = {"type": "http.request", "body": b"".join(chunks), "more_body": False}
        await self.app(scope, _replay([body], then=receive), send)

    async def _reject(self, send: Send) -> None:
        body = (
            b'{"detail":"request body too large: the limit is %d bytes '
            b'(CPKB_MAX_BODY_BYTES); send fewer points per request"}' % self.max_bytes
        )
        await send(
            {
                "type": "http.response.start",
                "status": 413,
                "headers": [
                    (b"content-type", b"application/json"),
                    (b"content-length", str(len(body)).encode()),
                ],
            }
        )
        await send({"type": "http.response.body", "body": body})


def _replay(messages: list[Message], then: Receive | None = None) -> Receive:
    """A `receive` that hands out `messages` first, then defers to `then` (disconnects)."""
    pending = list(messages)

    async def receive() -> Message:
        if pending:
            return pending.pop(0)
        if then is None:
            return {"type": "http.disconnect"}
        return await then()

    return receive


def install_security(app: FastAPI, settings: AccessSettings) -> None:
    """Attach the access policy, the browser login, the body-size limit, the access gate
    outside it and (only when configured) CORS outside both."""
    app.state.access_policy = AccessPolicy.from_settings(settings)
    app.include_router(login_router)
    app.add_middleware(BodySizeLimit, max_bytes=settings.max_body_bytes)
    app.add_middleware(AccessGate, policy=app.state.access_policy)
    if settings.cors_origins:
        app.add_middleware(
            CORSMiddleware,
            allow_origins=settings.cors_origins,
            allow_methods=["GET", "POST", "DELETE"],
            allow_headers=["Authorization", "Content-Type"],
        )
