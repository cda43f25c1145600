"""cpkb: a constraint-primitive knowledge base for task and motion planning."""

__version__ = "0.1.0"
