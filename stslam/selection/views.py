"""What a :class:`~stslam.selection.selector.ModelSelector` shows of its track: μ, points, filters, structures."""

from __future__ import annotations

import numpy as np

from stslam.errors import DegenerateFitError
from stslam.selection.model_filter import ModelFilter


class TrackViews:
    """Read-only views of a selector's ``log_mu``, observations, filters and settings (a mixin)."""

    @property
    def mu(self) -> np.ndarray | None:
        """Current μ (r,), or None before selection started."""
        return None if self.log_mu is None else np.exp(self.log_mu)

    @property
    def points(self) -> np.ndarray:
        """Every observation so far, shape (n, 3), m."""
        return np.array(self._points).reshape(-1, 3)

    def filter(self, name: str) -> ModelFilter:
        """The filter of model ``name``."""
        return self.filters[self.names.index(name)]

    def structure(self, name: str):
        return self.filter(name).structure  # latest fitted structure of model ``name`` (None if it never fitted)

    def final_structure(self, name: str):
        """Structure of model ``name`` fitted on every (thinned) observation so far; None if degenerate."""
        if len(self._points) == 0:
            return None
        try:
            return self.filter(name).model.fit(self._fit_window())
        except DegenerateFitError:
            return None

    def predicted_positions(self, name: str, n_ahead: int, dt: float | None = None) -> np.ndarray:
        """Next ``n_ahead`` mean positions (n_ahead, 3) under model ``name``'s filter."""
        f = self.filter(name)
        if f.structure is None:
            return np.empty((0, 3))
        return f.predicted_positions(n_ahead, self.settings.dt if dt is None else dt)
