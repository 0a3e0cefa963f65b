"""The EKF core, temporal motion models and the 1-D trace filter with its fitting (SPEC 3, 6)."""
