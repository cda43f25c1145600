"""Schemathesis over the app's own OpenAPI spec: whatever it sends, valid or not, no 500.

Positive and negative cases for every operation, bounded (examples per operation, derandomized)
so that the whole run stays within seconds.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import schemathesis
from fuzz_support import make_settings
from schemathesis.checks import not_a_server_error
from schemathesis.config import SchemathesisConfig

from server.app import create_app

_DB_DIR = tempfile.TemporaryDirectory(prefix="cpkb-schemathesis-")
_CONFIG = SchemathesisConfig.from_dict(
    {"seed": 8, "generation": {"mode": "all", "max-examples": 12, "deterministic": True}}
)
app = create_app(make_settings(Path(_DB_DIR.name) / "kb.sqlite"))
schema = schemathesis.openapi.from_asgi("/openapi.json", app, config=_CONFIG)


@schema.parametrize()
def test_no_input_gives_a_server_error(case: schemathesis.Case) -> None:
    case.call_and_validate(checks=[not_a_server_error])
