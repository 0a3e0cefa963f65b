"""The rendered RGB-D fridge scene and its feature-track front end (SPEC 9)."""
