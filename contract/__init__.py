"""The wire contract of the knowledge-base service: the pydantic models of every request and
answer (`contract.models`) and of the found bindings (`contract.bindings`), defined once.

The service (`server/`) and its client (`client/`) both import them, so the two sides cannot
drift; this package imports nothing of ours."""
