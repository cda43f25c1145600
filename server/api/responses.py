"""The error answers the routes declare in OpenAPI, in one shape: `{"detail": ...}`, a sentence
for the service's own errors and FastAPI's list of field errors for a 422 (as the service has
always answered, so clients keep working)."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, Field


class ErrorOut(BaseModel):
    """Every 400, 401, 404, 409, 413 and 503 answer."""

    detail: str = Field(
        description="What was wrong, in a sentence a user can act on.",
        examples=["knowledge base 'lab' not found"],
    )


class FieldError(BaseModel):
    loc: list[str | int] = Field(description="Where in the request: `body`, then the path.")
    msg: str = Field(description="What is wrong there.")
    type: str = Field(description="pydantic's error type (`missing`, `too_long`, ...).")


class ValidationErrorOut(BaseModel):
    """A 422: invalid input. `detail` is the list of field errors when the request does not
    fit the schema, a sentence when the service finds it invalid (a value outside a type's
    domain, a cursor it never gave out)."""

    detail: list[FieldError] | str = Field(
        description="The field errors, or one sentence naming the field."
    )


ERRORS: dict[int, tuple[str, str]] = {
    400: (
        "The body could not be read as JSON text (not UTF-8, say); nothing was stored.",
        "There was an error parsing the body",
    ),
    422: (
        "Invalid input: the answer names the field and never echoes large input back.",
        "points[0].x.#pose: 3 values for a 2-dimensional domain",
    ),
    401: (
        "No valid bearer token, where the service has one set (CPKB_TOKEN): every write and "
        "delete, and reads too with CPKB_AUTH_READS=true.",
        "a valid bearer token is required (Authorization: Bearer <token>)",
    ),
    404: ("No such knowledge base or type.", "knowledge base 'lab' not found"),
    409: (
        "The write conflicts with stored data: a name taken, an idempotency key reused for "
        "another point, a graph whose hash matches a type it is not isomorphic to.",
        "knowledge base 'lab' already exists",
    ),
    413: (
        "The body is over CPKB_MAX_BODY_BYTES; nothing was read or stored.",
        "request body too large: the limit is 33554432 bytes (CPKB_MAX_BODY_BYTES); send "
        "fewer points per request",
    ),
    503: (
        "The database is busy or unreachable, or surrogates are off (CPKB_SURROGATE__ENABLED): "
        "retry after Retry-After seconds.",
        "database busy or unreachable, retry: database is locked",
    ),
}


def errors(*codes: int) -> dict[int | str, dict[str, Any]]:
    """The `responses=` entry declaring each of `codes` with ErrorOut and an example."""
    declared: dict[int | str, dict[str, Any]] = {}
    for code in codes:
        description, example = ERRORS[code]
        entry: dict[str, Any] = {
            "model": _model(code),
            "description": description,
            "content": {"application/json": {"example": {"detail": example}}},
        }
        if code == 503:
            entry["headers"] = {
                "Retry-After": {"description": "Seconds to wait", "schema": {"type": "integer"}}
            }
        declared[code] = entry
    return declared


def json_errors(*codes: int) -> dict[int | str, dict[str, Any]]:
    """As `errors`, for a route whose own answer is not JSON: FastAPI files a declared model
    under the route's media type, so these name their (JSON) schema themselves."""
    declared = errors(*codes)
    for entry in declared.values():
        model = entry.pop("model")
        entry["content"]["application/json"]["schema"] = {
            "$ref": f"#/components/schemas/{model.__name__}"
        }
    return declared


def _model(code: int) -> type[BaseModel]:
    return ValidationErrorOut if code == 422 else ErrorOut


# Every route reads the database and may need a token; each adds what else it raises.
COMMON = errors(401, 503)
IN_KB = errors(401, 404, 503)  # a route under /v1/kbs/{kb}
INVALID = errors(422)  # on each route with parameters: FastAPI adds its own 422 otherwise
BODY = errors(400, 413, 422)  # a route that reads a JSON body
