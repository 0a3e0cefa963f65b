"""Online articulation model selection: the per-model filter, probabilities and selector (SPEC 4)."""
