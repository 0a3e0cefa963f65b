"""The one config edge: checked readers turning the composed config into settings (SPEC 12)."""
