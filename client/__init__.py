"""The light client side of cpkb: `CpkbClient` and its errors, speaking the wire contract
(`contract`)."""

from client.client import CpkbClient, split_urls
from client.errors import (
    BadRequest,
    Conflict,
    CpkbError,
    NotFound,
    ServerError,
    ServiceUnavailable,
    Unauthorized,
)

__all__ = [
    "BadRequest",
    "Conflict",
    "CpkbClient",
    "CpkbError",
    "NotFound",
    "ServerError",
    "ServiceUnavailable",
    "Unauthorized",
    "split_urls",
]
