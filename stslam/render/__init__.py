"""Figures, one module per experiment; every figure is a ``matplotlib.figure.Figure`` (no pyplot state)."""
