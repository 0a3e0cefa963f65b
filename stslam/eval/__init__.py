"""Metrics (ATE, RPE, axis errors) and Monte Carlo statistics (SPEC 7, 12)."""
