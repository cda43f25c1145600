"""The bench's output directory: an append-only JSONL of finished runs, resumable.

`runs.jsonl` gets one line per finished run, flushed and fsynced as it lands, so a bench
killed at any moment keeps every run it finished and a rerun skips them. Runs that raised
go to `errors.jsonl` and are retried by a rerun. `bench.json` pins the settings that make
results comparable (the rollout caps, the planner knobs set, the embedded service's settings
away from their defaults); a rerun with others is refused.
A `runs.jsonl.xz` or `.gz` beside it (how finished runs are kept in the repository) is read as
finished runs too.
"""

from __future__ import annotations

import gzip
import json
import lzma
import os
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

from cpkb.bench.scenarios import Scenario

RUNS_FILE = "runs.jsonl"
COMPRESSED_RUNS_FILES = ("runs.jsonl.xz", "runs.jsonl.gz")
ERRORS_FILE = "errors.jsonl"
GROUPS_FILE = "groups.jsonl"
CONFIG_FILE = "bench.json"
PINNED_DEFAULTS: Mapping[str, Any] = {
    "config": {},
    "concurrent": 1,
    "mixed": False,
    "service": {},
    "time_budget_s": None,
    "cores": None,
}
"""A setting a directory made before it was pinned holds at this value."""


class BenchConfigError(ValueError):
    """The output directory holds results made with other settings."""


def _read_jsonl(path: Path) -> Iterator[dict[str, Any]]:
    if not path.exists():
        return
    openers: dict[str, Callable[..., Any]] = {".xz": lzma.open, ".gz": gzip.open}
    opener = openers.get(path.suffix, open)
    with opener(path, "rt", encoding="utf-8") as handle:
        for line in handle:
            line = line.strip()
            if not line:
                continue
            try:
                record = json.loads(line)
            except json.JSONDecodeError:
                continue  # a line cut short by a kill mid-write: that run is simply redone
            if isinstance(record, dict):
                yield record


class ResultStore:
    """Reads and appends the results of one output directory (only the parent process writes)."""

    def __init__(self, out_dir: Path | str) -> None:
        self.out_dir = Path(out_dir)
        self.runs_path = self.out_dir / RUNS_FILE
        self.compressed_runs_paths = [self.out_dir / name for name in COMPRESSED_RUNS_FILES]
        self.errors_path = self.out_dir / ERRORS_FILE
        self.groups_path = self.out_dir / GROUPS_FILE
        self.config_path = self.out_dir / CONFIG_FILE

    def pin_config(self, config: Mapping[str, Any]) -> None:
        """Write the settings on first use; refuse a rerun whose settings differ."""
        self.out_dir.mkdir(parents=True, exist_ok=True)
        if self.config_path.exists():
            stored = json.loads(self.config_path.read_text(encoding="utf-8"))
            changed = {
                k: (old, v)
                for k, v in config.items()
                if (old := stored.get(k, PINNED_DEFAULTS.get(k))) != v
            }
            if changed:
                diff = ", ".join(
                    f"{k}: {old} here, {new} asked" for k, (old, new) in changed.items()
                )
                raise BenchConfigError(
                    f"{self.out_dir} holds results made with other settings ({diff}); "
                    "use another --out directory"
                )
            return
        self.config_path.write_text(json.dumps(dict(config), indent=2) + "\n", encoding="utf-8")

    def records(self) -> list[dict[str, Any]]:
        """Finished runs, one per scenario (the first line wins if a key repeats)."""
        seen: dict[tuple[str, str, int], dict[str, Any]] = {}
        paths = [*self.compressed_runs_paths, self.runs_path]
        for record in (r for path in paths for r in _read_jsonl(path)):
            try:
                key = (str(record["task"]), str(record["method"]), int(record["seed"]))
            except (KeyError, TypeError, ValueError):
                continue
            seen.setdefault(key, record)
        return list(seen.values())

    def errors(self) -> list[dict[str, Any]]:
        return list(_read_jsonl(self.errors_path))

    def groups(self) -> list[dict[str, Any]]:
        """The point counts of finished concurrent groups (`runner._check_group`)."""
        return list(_read_jsonl(self.groups_path))

    def finished(self) -> set[tuple[str, str, int]]:
        return {(r["task"], r["method"], int(r["seed"])) for r in self.records()}

    def pending(self, scenarios: list[Scenario]) -> list[Scenario]:
        done = self.finished()
        return [s for s in scenarios if s.key not in done]

    def append_run(self, record: Mapping[str, Any]) -> None:
        self._append(self.runs_path, record)

    def append_error(self, record: Mapping[str, Any]) -> None:
        self._append(self.errors_path, record)

    def append_group(self, record: Mapping[str, Any]) -> None:
        self._append(self.groups_path, record)

    def _append(self, path: Path, record: Mapping[str, Any]) -> None:
        self.out_dir.mkdir(parents=True, exist_ok=True)
        line = json.dumps(dict(record), sort_keys=True, default=str) + "\n"
        if path.exists() and path.stat().st_size > 0:
            with path.open("rb") as tail:
                tail.seek(-1, os.SEEK_END)
                if tail.read(1) != b"\n":
                    line = "\n" + line  # end a line cut short by a kill before adding ours
        with path.open("a", encoding="utf-8") as handle:
            handle.write(line)
            handle.flush()
            os.fsync(handle.fileno())
