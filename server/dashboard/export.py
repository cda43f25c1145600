"""A whole knowledge base as one zip: `types.json` (every type's summary, causal graph and
decision space, the surrogate state where one is fitted) and `points/<type_id>.csv` per type,
the same table as the per-type CSV route. Written to a spooled temporary file (memory up to a
bound, disk past it) and streamed out, so a large base does not sit in memory whole."""

from __future__ import annotations

import json
import tempfile
import zipfile
from collections.abc import Iterator
from contextlib import ExitStack
from datetime import UTC, datetime
from typing import IO

from server.db import Store
from server.hooks import ServiceHooks
from server.services import csv_tables, types

SPOOL_BYTES = 16 * 1024 * 1024
CHUNK_BYTES = 256 * 1024


def write_export(store: Store, hooks: ServiceHooks, kb: str, out: IO[bytes]) -> int:
    """Write the zip of `kb` to `out`; the number of types (NotFound for an unknown kb)."""
    summaries = types.list_types(store, kb)
    details = []
    with zipfile.ZipFile(out, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for s in summaries:
            detail = types.get_type(store, kb, s.type_id)
            state = hooks.surrogate(kb, s.type_id)
            record = detail.model_dump(mode="json", exclude={"surrogate"})
            record["surrogate"] = None if state is None else state.model_dump(mode="json")
            details.append(record)
            with archive.open(f"points/{s.type_id}.csv", "w") as member:
                for chunk in csv_tables.iter_csv(store, kb, s.type_id):
                    member.write(chunk.encode("utf-8"))
        meta = {"kb": kb, "exported_at": datetime.now(UTC).isoformat(), "types": details}
        archive.writestr("types.json", json.dumps(meta, indent=1))
    return len(summaries)


def export_stream(store: Store, hooks: ServiceHooks, kb: str) -> Iterator[bytes]:
    """The zip as chunks; written whole before the first chunk, so errors come before bytes."""
    with ExitStack() as on_error:
        spool = on_error.enter_context(tempfile.SpooledTemporaryFile(max_size=SPOOL_BYTES))
        write_export(store, hooks, kb, spool)
        spool.seek(0)
        on_error.pop_all()  # written: the stream closes it
    return _chunks(spool)


def _chunks(spool: IO[bytes]) -> Iterator[bytes]:
    with spool:
        while chunk := spool.read(CHUNK_BYTES):
            yield chunk
