"""The sheet of classified tracks: a panel per track, wrong ones marked."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.render.tracks import tracks_overview


def test_one_panel_per_track_and_wrong_titles_in_red():
    rng = np.random.default_rng(0)
    panels = [(np.cumsum(rng.normal(size=(30, 3)) * 0.01, axis=0), None, None, f"t{k}", k == 1) for k in range(7)]
    figure = tracks_overview(panels, columns=5)
    assert len(figure.axes) == 7
    colours = [a.title.get_color() for a in figure.axes]
    assert colours[1] == "tab:red" and all(c != "tab:red" for k, c in enumerate(colours) if k != 1)
    assert figure.get_size_inches()[0] == pytest.approx(2.7 * 5)  # five columns, two rows
    assert figure.get_size_inches()[1] == pytest.approx(2.6 * 2)


def test_no_panel_is_an_error():
    with pytest.raises(ValueError, match="at least one panel"):
        tracks_overview([])
