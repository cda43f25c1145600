"""Suite files as people read them: numbers and short lists on one line, the rest as blocks."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml


class _Dumper(yaml.SafeDumper):
    """Numbers and short lists on one line (`size: [0.05, 0.05, 0.2]`), the rest as blocks."""


def _list(dumper: yaml.SafeDumper, data: list) -> yaml.Node:
    flow = all(isinstance(v, int | float) for v in data) or (
        all(isinstance(v, str) for v in data) and sum(len(v) for v in data) < 60
    )
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


_Dumper.add_representer(list, _list)


def write_yaml(path: Path, data: dict[str, Any]) -> None:
    path.write_text(yaml.dump(data, Dumper=_Dumper, sort_keys=False, width=100))
