"""Fiducial markers in images: detection, the two IPPE poses of a square and the flip-free choice among them (SPEC 17)."""
