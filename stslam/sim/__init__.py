"""Simulated worlds, robot runs, door traces and marker tracks (SPEC 8)."""
