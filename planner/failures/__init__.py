"""Failed transitions as causal graphs with task-independent labels."""

from planner.failures.graphs import FailureGraph, failure_graph

__all__ = ["FailureGraph", "failure_graph"]
