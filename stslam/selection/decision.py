"""Decisions of online selection: the first one, revisions, the one standing at the end (docs/selection.md §1).

A *candidate* at step t is the model whose decision probability exceeds τ
and which the observations support (the selector's guards); a decision is a
candidate held for ``hold_steps`` consecutive steps. Algorithm 1 keeps the
first decision for ever (SPEC 4). With ``revise`` a later decision for
another model replaces it: the evidence of the whole run counts, not only
that of its first seconds. At the end of a track that moved at least
``min_motion_m`` but never produced a held candidate, the model of largest
decision probability is taken (``decided_by = "final"``).

Decision probabilities: μ from the filter bank, or, with a nested price
(:mod:`stslam.selection.nested_price`), μ with the prismatic/revolute split
replaced by the curvature Bayes factor B:

    p_static = μ_static,   p_revolute = (μ_p + μ_r)·B/(1 + B),   p_prismatic = (μ_p + μ_r)/(1 + B)

The filters' likelihoods tell moving from resting well; between the two
nested moving models their difference is the fit of a curvature, which B
prices with a prior (replacing, not multiplying, so that it is not counted twice).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from stslam.selection.probabilities import first_argmax_mismatch, logsumexp_finite


def decision_log_probabilities(names, log_mu, log_bayes_factor: float | None) -> np.ndarray:
    """log p (r,) from log μ (r,) and the revolute : prismatic log Bayes factor (module docstring)."""
    log_mu = np.asarray(log_mu, dtype=float)
    if log_bayes_factor is None or "prismatic" not in names or "revolute" not in names:
        return log_mu
    i, j = names.index("prismatic"), names.index("revolute")
    if not (np.isfinite(log_mu[i]) and np.isfinite(log_mu[j])):
        return log_mu
    moving = logsumexp_finite(log_mu[[i, j]])
    revolute_share, prismatic_share = _log_shares(float(log_bayes_factor))
    out = log_mu.copy()
    out[j] = moving - revolute_share  # log B/(1+B)
    out[i] = moving - prismatic_share  # log 1/(1+B)
    return out


@lru_cache(maxsize=64)
def _log_shares(log_bayes_factor: float) -> tuple[float, float]:
    """log(1 + 1/B) and log(1 + B): minus the logs of the revolute and prismatic shares B/(1+B), 1/(1+B)."""
    return np.logaddexp(0.0, -log_bayes_factor), np.logaddexp(0.0, log_bayes_factor)


class DecisionRecord:
    """The candidates of every step and the decisions they make (module docstring).

    Attributes
    ----------
    history : list[str or None]
        Candidate at each step.
    first, first_step : str or None, int or None
        The first decision and its step.
    standing, standing_step : str or None, int or None
        The latest decision and its step (the first one unless ``revise``).
    revisions : int
        How many times a later decision replaced the standing one.
    """

    def __init__(self, hold_steps: int, revise: bool):
        self.hold_steps = int(hold_steps)
        self.revise = bool(revise)
        self.history: list[str | None] = []
        self.first = self.first_step = None
        self.standing = self.standing_step = None
        self.revisions = 0
        self._run = (None, 0)  # (candidate, consecutive steps)

    def add(self, t: int, candidate: str | None) -> None:
        """Record step ``t``'s candidate and update the decisions."""
        self.history.append(candidate)
        name, count = self._run
        self._run = (candidate, count + 1 if candidate == name else 1)
        held = self.held
        if held is None:
            return
        if self.first is None:
            self.first, self.first_step = held, t
            self.standing, self.standing_step = held, t
        elif self.revise and held != self.standing:
            self.standing, self.standing_step = held, t
            self.revisions += 1

    @property
    def held(self) -> str | None:
        """The candidate of each of the last ``hold_steps`` steps (None if they differ or there was none)."""
        name, count = self._run
        return name if name is not None and count >= self.hold_steps else None

    @property
    def run_length(self) -> int:
        """For how many consecutive steps, up to the latest, the latest candidate has been the candidate."""
        return self._run[1]


class DecisionViews:
    """The decisions of a :class:`~stslam.selection.selector.ModelSelector` (its ``decisions``,
    ``settings``, ``log_mu``, μ rows and guards): Algorithm 1's names, μ's history and the decision for a
    finished track."""

    decisions: DecisionRecord

    @property
    def chosen(self) -> str | None:
        """The first decision (Algorithm 1's choice)."""
        return self.decisions.first

    @property
    def chosen_step(self) -> int | None:
        return self.decisions.first_step

    @property
    def current_history(self) -> list[str | None]:
        """The candidate of every step so far."""
        return self.decisions.history

    @property
    def mu_history(self) -> np.ndarray:
        """μ after each observation, shape (n, r); NaN rows before selection started."""
        with np.errstate(invalid="ignore"):
            return np.exp(np.array(self._log_mu_rows).reshape(-1, len(self.names)))

    def wrong_argmax_step(self, reference: str | None = None):
        """First step after the start at which arg-max μ is not ``reference`` (default: the final model).

        None if arg-max never disagrees (or there is no reference). Paper §VII-D: arg-max
        selection "would fail at frame 13" for its prismatic landmark.
        """
        reference = reference or self.final_model()
        if reference is None or self.start_step is None or reference not in self.names:
            return None
        return first_argmax_mismatch(self.mu_history, self.names.index(reference), self.start_step + 1)

    @property
    def held_model(self) -> str | None:
        """The model decided at each of the last ``hold_steps`` observations (None if they differ or none was)."""
        return self.decisions.held

    @property
    def held_steps(self) -> int:
        """For how many consecutive observations the latest candidate (:attr:`held_model` once held) has stood."""
        return self.decisions.run_length

    def final_model(self) -> str | None:
        """The decision for a finished track (offline use); with ``revise``, :meth:`final_decision`'s.

        The chosen model if there is one; otherwise, at the end of the track,
        the model whose μ exceeds τ now and which the observations support
        (:meth:`supported`), provided the track passed the motion gate — or,
        if it never did, ``"static"`` when μ_static > τ (it never moved);
        else None (undecided).
        """
        if self.settings.revise:
            return self.final_decision()[0]
        if self.chosen is not None:
            return self.chosen
        if self.log_mu is None:
            return None
        j = int(np.argmax(self.log_mu))
        if self.log_mu[j] <= np.log(self.settings.tau) or not self.supported(self.names[j]):
            return None
        if self._extent_m >= self.settings.min_motion_m or self.names[j] == "static":
            return self.names[j]
        return None

    def final_decision(self) -> tuple[str | None, int | None, str]:
        """(model, step, how) standing at the end: ``online`` (first), ``revised``, ``final`` or ``none``.

        A track that moved at least ``min_motion_m`` always ends decided: without a
        held decision, the model of largest decision probability at the end (``final``).
        """
        d = self.decisions
        if d.standing is not None:
            return d.standing, d.standing_step, "revised" if d.revisions else "online"
        if self.log_mu is None or self._extent_m < self.settings.min_motion_m:
            return None, None, "none"
        return self.names[int(np.argmax(self.decision_log_mu()))], len(self._points) - 1, "final"

    def decision_step(self) -> int | None:
        """Step of :meth:`final_model`'s decision: the chosen step, or the last step."""
        if self.settings.revise:
            return self.final_decision()[1]
        if self.chosen is not None:
            return self.chosen_step
        return None if self.final_model() is None else len(self._points) - 1
