"""File formats at the edges: TUM, trace CSV, track files, MCAP, results folders (SPEC 9, 12)."""
