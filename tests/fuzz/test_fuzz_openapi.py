"""Schemathesis over the app's own OpenAPI spec: whatever it sends, valid or not, no 500.

Positive and negative cases for every operation, bounded (examples per operation, derandomized)
so that the whole run stays within seconds.

The schema comes from `app.openapi()`, not from a request to the app: a request would start the
app's lifespan (its fit threads) while pytest is still collecting, and those threads would run
beside the assertion rewriting of every later test module (CPython 3.11's `ast.parse` is not
safe beside another thread that parses; see python/cpython#106905). The lifespan starts with
the first case instead, and `stopped_app` ends it after the module's last case.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
import schemathesis
from fuzz_support import make_settings
from schemathesis.checks import not_a_server_error
from schemathesis.config import SchemathesisConfig
from schemathesis.python.asgi import shutdown_lifespans

from server.app import create_app

_DB_DIR = tempfile.TemporaryDirectory(prefix="cpkb-schemathesis-")
_CONFIG = SchemathesisConfig.from_dict(
    {"seed": 8, "generation": {"mode": "all", "max-examples": 12, "deterministic": True}}
)
app = create_app(make_settings(Path(_DB_DIR.name) / "kb.sqlite"))
schema = schemathesis.openapi.from_dict(app.openapi(), config=_CONFIG)
schema.app = app


@pytest.fixture(scope="module", autouse=True)
def stopped_app() -> Iterator[None]:
    """The app's lifespan (and its fit threads) ends with this module, not at interpreter exit."""
    yield
    shutdown_lifespans()
    _DB_DIR.cleanup()


@schema.parametrize()
def test_no_input_gives_a_server_error(case: schemathesis.Case) -> None:
    case.call_and_validate(checks=[not_a_server_error])
