"""Service commands: `cpkb serve`, `cpkb db upgrade`, `cpkb kb list|create|delete`, `cpkb types`."""

from __future__ import annotations

import argparse
import os
import socket
from typing import Any

from cpkb.cli import CliError
from cpkb.cli.reach import checked_url, explained


def register(subparsers: Any) -> None:
    serve = subparsers.add_parser(
        "serve",
        help="run the knowledge-base service",
        description="Serve the knowledge base over HTTP: the API under /v1, its documentation "
        "at /docs, the dashboard at / and Prometheus metrics at /metrics. The database is "
        "migrated first. Writes and deletes need a bearer token when CPKB_TOKEN is set. Logs "
        "are JSON lines on stderr. Stop it with Ctrl-C.",
        epilog="Example: cpkb serve --db sqlite:///lab.db --port 8000",
    )
    serve.add_argument(
        "--db",
        metavar="URL",
        help="database URL (default: CPKB_DATABASE_URL "
        "or sqlite:///cpkb.db in the current directory)",
    )
    serve.add_argument("--host", help="address to bind (default 127.0.0.1)")
    serve.add_argument("--port", type=int, help="port (default 8000)")
    serve.add_argument("--log-level", default=None, help="uvicorn log level (default info)")
    serve.add_argument(
        "--cpu-cores",
        metavar="LIST",
        help="run the service and its fits on these cores only, e.g. 1 or 1-3 (Linux; default: "
        "CPKB_CPU_CORES, else any core)",
    )
    serve.set_defaults(handler=_serve)

    db = subparsers.add_parser("db", help="database maintenance")
    db_sub = db.add_subparsers(dest="db_command", required=True, metavar="ACTION")
    upgrade = db_sub.add_parser(
        "upgrade",
        help="migrate the database to the latest schema",
        description="Migrate the database to the latest schema (serve does this too) and print "
        "its revision; creates the tables of a new database.",
    )
    upgrade.add_argument("--db", metavar="URL", help="database URL (default as for serve)")
    upgrade.set_defaults(handler=_db_upgrade)

    kb = subparsers.add_parser("kb", help="list, create or delete knowledge bases")
    kb_sub = kb.add_subparsers(dest="kb_command", required=True, metavar="ACTION")
    kb_list = kb_sub.add_parser(
        "list",
        help="knowledge bases with type and point counts",
        description="List the knowledge bases of a running service (`cpkb serve`), with how "
        "many types and points each holds.",
    )
    _client_options(kb_list)
    kb_list.set_defaults(handler=_kb_list)
    for action, helptext, handler in (
        ("create", "create a knowledge base", _kb_create),
        ("delete", "delete a knowledge base with all its types and points", _kb_delete),
    ):
        cmd = kb_sub.add_parser(
            action,
            help=helptext,
            description=f"{helptext[0].upper()}{helptext[1:]}, on a "
            "running service (`cpkb serve`); needs --token when the service has one set.",
        )
        cmd.add_argument("name", help="letters, digits, _ . - (e.g. lab)")
        _client_options(cmd)
        cmd.set_defaults(handler=handler)

    types = subparsers.add_parser(
        "types",
        help="the CP types of a knowledge base, as a table",
        description="One row per CP type (a kind of failure with its decisions and context) "
        "of a knowledge base on a running service: its points, how many infeasible, and "
        "whether its surrogate has been fitted on them. Pipe it (`| cat`) for whole type ids "
        "on one line each.",
    )
    types.add_argument("--kb", default="default", help="knowledge base (default: default)")
    _client_options(types)
    types.set_defaults(handler=_types)

    found = subparsers.add_parser(
        "bindings",
        help="the binding lists planners found, as a table",
        description="One row per binding list a planner stored when it solved its task, on a "
        "running service: the runs of the same task follow each as their next rollout "
        "(knowledge.follow_found). The oldest first.",
    )
    found.add_argument("--kb", default="default", help="knowledge base (default: default)")
    found.add_argument("--task", help="only this task's")
    found.add_argument(
        "--limit", type=int, help="at most this many (default and most: one page's worth)"
    )
    _client_options(found)
    found.set_defaults(handler=_bindings)


def _client_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--kb-url",
        "--url",
        dest="url",
        help="service URL, as `cpkb plan --kb-url` takes it; replicas as URL1,URL2 (default: "
        "CPKB_URL or http://127.0.0.1:8000)",
    )
    parser.add_argument("--token", help="access token (default: CPKB_TOKEN)")


def _settings(**overrides: Any) -> Any:
    from pydantic import ValidationError

    from server.settings import Settings

    try:
        return Settings(**{k: v for k, v in overrides.items() if v is not None})
    except ValidationError as exc:
        first = exc.errors()[0]
        field = ".".join(str(p) for p in first["loc"])
        raise CliError(f"bad setting {field}: {first['msg']}") from exc


def _pin(cpu_cores: str) -> None:
    """Keep the service (its threads and the fit worker it starts later) on `cpu_cores`."""
    from server.cpus import parse_cpu_list, pin_process

    if not hasattr(os, "sched_setaffinity"):
        raise CliError("--cpu-cores needs Linux (this platform cannot pin a process to cores)")
    try:
        pin_process(parse_cpu_list(cpu_cores))
    except OSError as exc:
        raise CliError(f"cannot run on cores {cpu_cores}: {exc.strerror or exc}") from exc


def _shown(url: str) -> str:
    from sqlalchemy.engine import make_url

    try:
        return make_url(url).render_as_string(hide_password=True)
    except Exception:
        return url


def _open_store(url: str) -> Any:
    from server.db import DatabaseUrlError, Store

    try:
        return Store.from_url(url)
    except DatabaseUrlError as exc:
        raise CliError(str(exc)) from exc


def _prepare(store: Any, url: str) -> None:
    from sqlalchemy.exc import SQLAlchemyError

    from server.errors import ServiceError
    from server.schema import prepare_database

    try:
        prepare_database(store)
    except ServiceError as exc:
        raise CliError(f"cannot open the database {_shown(url)}: {exc.detail}") from exc
    except SQLAlchemyError as exc:
        reason = str(getattr(exc, "orig", None) or exc).strip().splitlines()[0]
        raise CliError(f"cannot open the database {_shown(url)}: {reason}") from exc


def _serve(args: argparse.Namespace) -> int:
    settings = _settings(
        database_url=args.db,
        host=args.host,
        port=args.port,
        log_level=args.log_level,
        cpu_cores=args.cpu_cores,
    )
    if settings.cpu_cores is not None:
        _pin(settings.cpu_cores)
    # Take the port first, so that a port in use fails before the database is touched; then
    # check the database before importing the web stack (and the surrogates' torch).
    listener = _listen(settings.host, settings.port)
    with listener:
        store = _open_store(settings.database_url)
        _prepare(store, settings.database_url)
        store.dispose()
        if settings.surrogate.nice > 0 and hasattr(os, "nice"):
            os.nice(settings.surrogate.nice)  # the fit worker, started later, inherits it

        import uvicorn

        from server.app import create_app
        from server.security import SecurityConfigError

        try:
            app = create_app(settings)
        except SecurityConfigError as exc:
            raise CliError(str(exc)) from exc
        url = served_url(settings.host, listener.getsockname()[1])
        print(
            f"cpkb: serving {_shown(settings.database_url)} at {url} (the dashboard; API docs "
            f"at {url}docs); Ctrl-C stops it",
            flush=True,
        )
        from server.observability import configure_json_logging

        # One JSON line per record on stderr: uvicorn's own loggers propagate to the root
        # (log_config=None) and the service's access log replaces uvicorn's plain one.
        configure_json_logging(settings.log_level)
        config = uvicorn.Config(
            app, log_config=None, log_level=settings.log_level, access_log=False
        )
        uvicorn.Server(config).run(sockets=[listener])
    return 0


def served_url(host: str, port: int) -> str:
    """The URL to open for a service listening on host:port: a wildcard address is reached on
    loopback from this machine, an IPv6 address goes in brackets."""
    shown = {"0.0.0.0": "127.0.0.1", "::": "[::1]", "": "127.0.0.1"}.get(host, host)
    if ":" in shown and not shown.startswith("["):
        shown = f"[{shown}]"
    return f"http://{shown}:{port}/"


def _listen(host: str, port: int) -> socket.socket:
    """A listening socket on host:port (as uvicorn would bind it), or a one-line CLI error."""
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)
    except socket.gaierror as exc:
        raise CliError(f"cannot listen on {host}:{port}: {exc.strerror}") from None
    family, kind, proto, _, address = infos[0]
    listener = socket.socket(family, kind, proto)
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        listener.bind(address)
        listener.listen(2048)
    except OSError as exc:
        listener.close()
        raise CliError(
            f"cannot listen on {host}:{port}: {exc.strerror} (is another service running "
            "there? pick another --port)"
        ) from None
    return listener


def _db_upgrade(args: argparse.Namespace) -> int:
    from migrations import current_revision

    settings = _settings(database_url=args.db)
    store = _open_store(settings.database_url)
    _prepare(store, settings.database_url)
    print(f"{_shown(settings.database_url)}: schema at revision {current_revision(store.engine)}")
    store.dispose()
    return 0


def _run(args: argparse.Namespace, call: Any) -> Any:
    """`call(client)`, a failed call to the service as the one-line error (exit 3) that `plan`
    and `bench` give too."""
    from client import CpkbClient, CpkbError

    settings = _settings(url=args.url)
    url = checked_url(settings.url)
    token = args.token or (settings.token.get_secret_value() if settings.token else None)
    with CpkbClient(url, timeout=30.0, retries=2, backoff=0.1, token=token) as client:
        try:
            return call(client)
        except CpkbError as exc:
            raise explained(exc, url, token) from None


def _console() -> Any:
    """A rich console; when piped, wide enough that rows stay whole lines (grep-able)."""
    from rich.console import Console

    console = Console()
    return console if console.is_terminal else Console(width=240)


def _kb_list(args: argparse.Namespace) -> int:
    from rich.table import Table

    kbs = _run(args, lambda c: c.list_kbs())
    table = Table("knowledge base", "types", "points", "created", box=None)
    for kb in kbs:
        created = kb.created_at.strftime("%Y-%m-%d %H:%M") if kb.created_at else ""
        table.add_row(kb.name, str(kb.n_types), str(kb.n_points), created)
    _console().print(table)
    return 0


def _kb_create(args: argparse.Namespace) -> int:
    from pydantic import ValidationError

    try:
        kb = _run(args, lambda c: c.create_kb(args.name))
    except ValidationError as exc:
        raise CliError(
            f"bad knowledge base name {args.name!r}: use letters, digits, _ . -"
        ) from exc
    print(f"created knowledge base {kb.name!r}")
    return 0


def _kb_delete(args: argparse.Namespace) -> int:
    _run(args, lambda c: c.delete_kb(args.name))
    print(f"deleted knowledge base {args.name!r}")
    return 0


def _types(args: argparse.Namespace) -> int:
    from rich.table import Table

    types = _run(args, lambda c: c.list_types(args.kb))
    console = _console()
    if not types:
        console.print(f"knowledge base {args.kb!r} has no types yet")
        return 0
    details = _run(args, lambda c: [c.get_type(args.kb, t.type_id) for t in types])
    differences = _differences(details)
    columns = ["failure", "decisions", "context"]
    columns += ["differs in"] if differences else []
    columns += ["points", "infeasible", "fit", "fitted", "updated"]
    caption = (
        "fit: the surrogate's state (ready, fitting, queued, prior, error); fitted: points in "
        "its latest fit / points stored (a fit has landed when they are equal)"
    )
    if differences:
        caption += (
            "; differs in: what tells apart types of one failure, decisions and context "
            "(the edges only that type has)"
        )
    ids = {t.type_id: t.type_id for t in types}
    if console.is_terminal and console.width < WIDE:
        ids = _short_ids(list(ids))
        caption += "; type: the start of its id, unique here (`cpkb types | cat` prints them whole)"
    table = Table(
        "type",
        *columns,
        title=f"knowledge base {args.kb!r}: {len(types)} types",
        caption=caption,
    )
    table.columns[0].no_wrap = True  # the id is what a user copies into an API call
    for column in table.columns[1:]:
        column.overflow = "fold"  # a long name wraps, never ends in an ellipsis
    for t, detail in zip(types, details, strict=True):
        updated = t.updated_at.strftime("%Y-%m-%d %H:%M:%S") if t.updated_at else ""
        fit, fitted = _fit_state(detail.surrogate, t.n_points)
        cells = [t.failure, ", ".join(t.decisions), ", ".join(t.context)]
        cells += [differences.get(t.type_id, "")] if differences else []
        cells += [str(t.n_points), str(t.n_infeasible), fit, fitted, updated]
        table.add_row(ids[t.type_id], *cells)
    console.print(table)
    return 0


def _bindings(args: argparse.Namespace) -> int:
    from rich.table import Table

    from contract.bindings import MAX_BINDINGS_PAGE

    limit = MAX_BINDINGS_PAGE if args.limit is None else args.limit
    if not 1 <= limit <= MAX_BINDINGS_PAGE:
        raise CliError(f"--limit must be between 1 and {MAX_BINDINGS_PAGE}, not {limit}")
    page = _run(args, lambda c: c.bindings(args.kb, task=args.task, limit=limit))
    console = _console()
    if not page.bindings:
        console.print(f"knowledge base {args.kb!r} holds no found bindings yet")
        return 0
    table = Table("id", "task", "run", "rollout", "bindings", "found", box=None)
    for found in page.bindings:
        when = found.created_at.strftime("%Y-%m-%d %H:%M:%S") if found.created_at else ""
        values = "  ".join(f"{var}={_compact(value)}" for var, value in found.bindings.items())
        rollout = "" if found.rollout is None else str(found.rollout)
        table.add_row(str(found.binding_id), found.task, found.run or "", rollout, values, when)
    console.print(table)
    return 0


def _compact(value: Any) -> str:
    return value if isinstance(value, str) else "[" + ", ".join(f"{v:.3g}" for v in value) + "]"


WIDE = 160  # columns a terminal needs for whole type ids beside the rest


def _short_ids(type_ids: list[str]) -> dict[str, str]:
    """Each id cut to the shortest length (8 at least) at which they all stay distinct."""
    for length in range(8, max(map(len, type_ids)) + 1):
        if len({t[:length] for t in type_ids}) == len(type_ids):
            return {t: t[:length] for t in type_ids}
    return {t: t for t in type_ids}


def _differences(details: list[Any]) -> dict[str, str]:
    """For types that share failure, decisions and context (so their rows look alike), the
    edges of each that not all of them have; a difference of domains only is named so."""
    groups: dict[tuple, list[Any]] = {}
    for d in details:
        groups.setdefault((d.failure, tuple(d.decisions), tuple(d.context)), []).append(d)
    out: dict[str, str] = {}
    for members in groups.values():
        if len(members) < 2:
            continue
        edges = {d.type_id: _edges(d.graph) for d in members}
        common = set.intersection(*edges.values())
        for d in members:
            own = sorted(edges[d.type_id] - common)
            out[d.type_id] = "; ".join(own) if own else "domains or repeated edges"
    return out


def _edges(graph: Any) -> set[str]:
    """A graph's edges by the labels of their ends (ids are arbitrary), as `a -label-> b`."""
    label = {n.id: n.label for n in graph.nodes}
    return {
        f"{label[e.source]} -{e.label}-> {label[e.target]}"
        if e.label
        else f"{label[e.source]} -> {label[e.target]}"
        for e in graph.edges
    }


def _fit_state(state: Any, n_points: int) -> tuple[str, str]:
    """The surrogate's status (`pending` added while points wait for a fit) and n_fitted/n."""
    if state is None:
        return "off", "-"
    status = state.status
    if state.n_fitted < n_points and status not in ("fitting", "queued"):
        status = f"{status}, pending"
    version = f" v{state.version}" if state.version is not None else ""
    return status + version, f"{state.n_fitted}/{n_points}"
