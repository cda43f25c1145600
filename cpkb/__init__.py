"""cpkb: a constraint-primitive knowledge base for task and motion planning."""
