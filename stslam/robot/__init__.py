"""The planar robot's motion model and the range-bearing-elevation and pinhole sensors (SPEC 5)."""
