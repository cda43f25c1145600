"""Failed transitions as causal graphs with task-independent labels."""

from planner.failures.graphs import Encodings, FailureGraph, failure_graph

__all__ = ["Encodings", "FailureGraph", "failure_graph"]
