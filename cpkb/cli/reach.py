"""Knowledge-base problems as one-line CLI errors with their own exit status.

`cpkb plan` and `cpkb bench` probe a given service before any work starts (a world loaded, a
progress bar drawn, workers forked), so a wrong URL or a missing token fails in a second
rather than after a run's retries, and never as a traceback.
"""

from __future__ import annotations

import contextlib
import uuid

from cpkb.cli import CliError

KB_UNAVAILABLE_STATUS = 3
EXIT_STATUS_HELP = (
    f"{KB_UNAVAILABLE_STATUS} when the knowledge base cannot be reached or refuses the request "
    "(wrong URL, no service running, a missing or wrong token, an error answer)"
)


class KnowledgeBaseUnavailable(CliError):
    """The knowledge base cannot be reached or refused the request."""

    exit_status = KB_UNAVAILABLE_STATUS


def checked_url(url: str, option: str = "--kb-url") -> str:
    """`url` if it is an absolute http(s) URL, or several joined by commas (replicas of one
    service: the client fails over between them); else a usage error that says how to write one."""
    import httpx

    parts = [part.strip() for part in url.split(",")]
    if not all(parts):
        raise CliError(f"{option} {url!r} has an empty URL (write URL1,URL2 for replicas)")
    for part in parts:
        try:
            parsed = httpx.URL(part)
        except httpx.InvalidURL as exc:
            raise CliError(f"{option} {part!r} is not a URL: {exc}") from None
        if parsed.scheme not in ("http", "https") or not parsed.host:
            hint = f" (did you mean http://{part}?)" if "://" not in part else ""
            raise CliError(f"{option} {part!r} is not an http:// or https:// URL{hint}")
    return url


def explained(exc: Exception, url: str, token: str | None) -> CliError:
    """The one-line CLI error for a failed call to the knowledge base at `url`."""
    from client import CpkbError, ServiceUnavailable, Unauthorized
    from cpkb.embedded import EmbeddedServiceError

    if isinstance(exc, EmbeddedServiceError):
        last = str(exc).strip().splitlines()
        return KnowledgeBaseUnavailable(
            f"the embedded knowledge base did not start: {last[-1] if last else exc}"
        )
    if isinstance(exc, ServiceUnavailable) and exc.status is None:
        return KnowledgeBaseUnavailable(
            f"cannot reach the knowledge base at {url} (start one with `cpkb serve`, "
            "or leave out --kb-url for an embedded one)"
        )
    if isinstance(exc, Unauthorized):
        remedy = (
            "check --token or CPKB_TOKEN"
            if token
            else "it needs a token: pass --token or set CPKB_TOKEN"
        )
        return KnowledgeBaseUnavailable(
            f"the knowledge base at {url} refused the request ({exc.status}): {remedy}"
        )
    if isinstance(exc, CpkbError):
        reason = " ".join(str(exc).split())
        return KnowledgeBaseUnavailable(f"the knowledge base at {url} answered {reason}")
    reason = " ".join(str(exc).split()) or type(exc).__name__
    return KnowledgeBaseUnavailable(f"cannot use the knowledge base at {url}: {reason}")


def checked_kb_name(name: str) -> str:
    """`name` if the service would take it as a knowledge base's name; else a usage error."""
    from pydantic import ValidationError

    from contract.models import KnowledgeBaseIn

    try:
        KnowledgeBaseIn(name=name)
    except ValidationError as exc:
        raise CliError(f"bad knowledge base name {name!r}: {exc.errors()[0]['msg']}") from None
    return name


def probe(url: str, token: str | None, kb: str | None = None) -> None:
    """Check that the service at `url` answers and takes this token for writes.

    With `kb`, creates that knowledge base if it is missing (what a planner run does first).
    Either way it deletes a knowledge base that cannot exist, which touches nothing yet needs
    the write permission a run will need (finding `kb` already there needs only a read).
    """
    from client import CpkbClient, CpkbError, NotFound

    checked_url(url)
    if kb is not None:
        checked_kb_name(kb)
    try:
        with CpkbClient(url, token=token, retries=1, backoff=0.1, reconnect_for=0.0) as client:
            client.health()
            if kb is not None:
                client.create_kb(kb, exist_ok=True)
            with contextlib.suppress(NotFound):
                client.delete_kb(f"cpkb-probe-{uuid.uuid4().hex}")
    except CpkbError as exc:
        raise explained(exc, url, token) from None


def _names_in_database(db_url: str | None) -> list[str] | None:
    """The knowledge bases of the database an embedded service would open, read directly
    (nothing created: a missing SQLite file holds none); None when it cannot be read, which
    the service's own start then reports."""
    from pathlib import Path

    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import SQLAlchemyError

    from server.db import DatabaseUrlError, Store
    from server.errors import ServiceError
    from server.services import kbs
    from server.settings import Settings

    url = db_url or Settings().database_url
    try:
        parsed = make_url(url)
        on_file = parsed.get_backend_name() == "sqlite" and parsed.database not in (None, "")
        if on_file and parsed.database != ":memory:" and not Path(str(parsed.database)).exists():
            return []
        store = Store.from_url(url)
        try:
            return [kb.name for kb in kbs.list_kbs(store)]
        finally:
            store.dispose()
    except (SQLAlchemyError, ServiceError, DatabaseUrlError, ImportError):
        return None  # the embedded service's start says why


def require_kb(kb: str, url: str | None, token: str | None) -> None:
    """A usage error unless knowledge base `kb` exists at `url` (None: the embedded service's
    database); `default` always does (the service makes it). So a misspelt `--kb` fails at
    once instead of starting a run that learns from nothing."""
    from client import CpkbClient, CpkbError
    from server.services.kbs import DEFAULT_KB

    if kb == DEFAULT_KB:
        return
    if url is None:
        names = _names_in_database(None)
        where = "in the embedded service's database"
        if names is None:
            return
    else:
        where = f"at {url}"
        try:
            with CpkbClient(url, token=token, retries=1, backoff=0.1) as client:
                names = [b.name for b in client.list_kbs()]
        except CpkbError as exc:
            raise explained(exc, url, token) from None
    if kb not in names:
        known = ", ".join(sorted(names)) or "none"
        raise CliError(
            f"knowledge base {kb!r} does not exist {where} (it has: {known}); "
            "pass --create-kb to start a new, empty one"
        )
