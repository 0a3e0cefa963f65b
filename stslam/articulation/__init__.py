"""Articulation models, their structure fits, bounds, evidence and the hinge axis (SPEC 2)."""
