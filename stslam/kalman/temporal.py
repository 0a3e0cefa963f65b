"""Temporal models of the motion variable q(t) (SPEC 3, paper Eq. motion_parameter_prop).

Order k keeps the state X = [q, q⁽¹⁾, …, q⁽ᵏ⁾] (dimension k+1); white noise η
drives the (k+1)-th derivative: X_{t+1} = A X_t + B η, η ~ N(0, σ_η²).
Order 0 is a random walk, 1 constant velocity, 2 constant acceleration.

The initial state comes from a short window of q by a Gaussian-weighted local
polynomial fit evaluated at the window's last sample (SPEC 3 initialisation).
Away from the ends of a signal such a fit of degree 1 is the derivative-of-
Gaussian filter with its kernel normalised to unit first moment; at the end it
stays exact for every polynomial up to its degree, where a convolution padded
by repeating the last sample is not (it halves the slope of a ramp).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from math import factorial

import numpy as np

from stslam.errors import DegenerateFitError

# Gaussian weights below this are raised to it, so that a long window keeps
# every sample in a full-rank fit (exp(-½·6²) ≈ 1.5e-8: only samples more than
# about six widths from the end are affected, and only by that much).
MIN_WEIGHT = 1e-8
PROCESS_NOISE_MODELS = ("identity", "taylor")


def _check_order(order: int, name: str = "order") -> int:
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 0:
        raise ValueError(f"{name}: expected an integer ≥ 0, got {order!r}")
    return int(order)


def _check_dt(dt: float) -> float:
    if isinstance(dt, bool) or not isinstance(dt, (int, float, np.floating, np.integer)) \
            or not np.isfinite(dt) or not dt > 0:
        raise ValueError(f"dt: expected a finite time step > 0, got {dt!r}")
    return float(dt)


def _check_width(width: float, name: str) -> float:
    if not (np.isfinite(width) and width > 0):
        raise ValueError(f"{name}: expected a width > 0, got {width!r}")
    return width


def transition_matrices(order: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Transition matrix A and noise input B of the order-k Taylor model (SPEC 3).

    A[i, j] = δt^(j−i)/(j−i)! for j ≥ i, else 0;  B[i] = δt^(k+1−i)/(k+1−i)!.
    A equals expm(N·δt) for the shift matrix N (N[i, i+1] = 1), the exact
    discretisation of the continuous chain of integrators.

    Parameters
    ----------
    order : int
        Temporal order k ≥ 0.
    dt : float
        Time step δt (s, or samples when δt = 1).

    Returns
    -------
    A : numpy.ndarray, shape (k+1, k+1)
    B : numpy.ndarray, shape (k+1,)
    """
    k = _check_order(order)
    dt = _check_dt(dt)
    A = np.zeros((k + 1, k + 1))
    for i in range(k + 1):
        for j in range(i, k + 1):
            A[i, j] = dt ** (j - i) / factorial(j - i)  # SPEC 3
    B = np.array([dt ** (k + 1 - i) / factorial(k + 1 - i) for i in range(k + 1)])  # SPEC 3
    return A, B


def process_noise(order: int, dt: float, sigma_eta: float) -> np.ndarray:
    """Process noise Q = B Bᵀ σ_η² of the order-k model (SPEC 3), shape (k+1, k+1).

    σ_η is the standard deviation of η, in units of q per s^(k+1).
    """
    _, B = transition_matrices(order, dt)
    return np.outer(B, B) * sigma_eta**2


def noise_matrix(order: int, dt: float, sigma_eta: float, model: str) -> np.ndarray:
    """Process noise Q of one step of one axis, shape (k+1, k+1).

    ``"taylor"``: Q = σ_η² B Bᵀ (SPEC 3, η on the (k+1)-th derivative).
    ``"identity"``: Q = σ_η² I, whatever δt (the paper's filter, SPEC 8.2, used
    0.01·I, i.e. σ_η = 0.1).
    """
    if model == "taylor":
        return process_noise(order, dt, sigma_eta)
    if model == "identity":
        return sigma_eta**2 * np.eye(order + 1)
    raise ValueError(f"model: expected one of {', '.join(PROCESS_NOISE_MODELS)}; got {model!r}")


@dataclass(frozen=True)
class MotionModel:
    """The order-k model of a motion variable q with ``dof`` axes (SPEC 3), its matrices cached per δt.

    The state X = [q, q⁽¹⁾, …, q⁽ᵏ⁾] is stacked per derivative (blocks of
    ``dof`` entries), so the one-axis model lifts to the whole state by a
    Kronecker product, each axis with independent noise η ~ N(0, σ_η²) on its
    (k+1)-th derivative:

        X_{t+1} = F X_t + w,  F = A ⊗ I_dof,  w ~ N(0, Q),  Q = Q₁ ⊗ I_dof,

    A from :func:`transition_matrices` and Q₁ from :func:`noise_matrix`
    (``noise``). The returned matrices are shared and read-only.

    Attributes
    ----------
    order : int
        Temporal order k ≥ 0.
    dof : int
        Number of axes of q, ≥ 1.
    sigma_eta : float
        Standard deviation of η (units of q per time^(k+1)), ≥ 0.
    noise : {"taylor", "identity"}
        Process-noise model of one axis (:func:`noise_matrix`).
    """

    order: int
    dof: int = 1
    sigma_eta: float = 0.0
    noise: str = "taylor"
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        _check_order(self.order)
        if isinstance(self.dof, bool) or not isinstance(self.dof, (int, np.integer)) or self.dof < 1:
            raise ValueError(f"dof: expected an integer ≥ 1, got {self.dof!r}")
        if not (np.isfinite(self.sigma_eta) and self.sigma_eta >= 0):
            raise ValueError(f"sigma_eta: expected a finite number ≥ 0, got {self.sigma_eta!r}")
        if self.noise not in PROCESS_NOISE_MODELS:
            raise ValueError(f"noise: expected one of {', '.join(PROCESS_NOISE_MODELS)}; got {self.noise!r}")

    @property
    def size(self) -> int:
        """Dimension (k+1)·dof of the state X."""
        return (self.order + 1) * self.dof

    def matrices(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Transition F and process noise Q over a step δt (s), each shape ((k+1)·dof, (k+1)·dof)."""
        key = _check_dt(dt)
        if key not in self._cache:
            A, _ = transition_matrices(self.order, key)
            eye = np.eye(self.dof)
            F = np.kron(A, eye)  # SPEC 3, per axis
            Q = np.kron(noise_matrix(self.order, key, self.sigma_eta, self.noise), eye)
            F.flags.writeable = False
            Q.flags.writeable = False
            self._cache[key] = (F, Q)
        return self._cache[key]


def derivative_operator(times, order: int, sigma_time: float, degree: int | None = None) -> np.ndarray:
    """Linear map from a window of samples to [q, q⁽¹⁾, …, q⁽ᵏ⁾] at its last time (SPEC 3).

    A polynomial of degree p = ``degree`` (default max(k, 1)) in the time lag
    τ_j = t_j − t_last is fitted by weighted least squares with Gaussian weights
    w_j = exp(−½ (τ_j / σ)²) (floored at ``MIN_WEIGHT``); the d-th derivative at
    the last time is d!·c_d. Any polynomial of degree ≤ p is reproduced exactly.
    Derivatives above p are set to 0.

    Parameters
    ----------
    times : array_like, shape (n,)
        Strictly increasing sample times (s).
    order : int
        Temporal order k (rows of the result).
    sigma_time : float
        Width σ of the Gaussian weights (s), > 0.
    degree : int, optional
        Polynomial degree p; defaults to max(k, 1) and is capped at n − 1.

    Returns
    -------
    numpy.ndarray, shape (k+1, n)
        L with X = L q for samples q (so Cov X = σ_obs² L Lᵀ for white noise).

    Raises
    ------
    DegenerateFitError
        Fewer than two samples, or times that are not strictly increasing.
    ValueError
        A negative or non-integer ``order`` or ``degree``, or a width ``sigma_time`` that is not > 0.
    """
    k = _check_order(order)
    t = np.asarray(times, dtype=float).reshape(-1)
    if t.size < 2:
        raise DegenerateFitError(f"derivatives need at least 2 samples in the window, got {t.size}")
    if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0):
        raise DegenerateFitError(f"window times must be finite and strictly increasing, got {t!r}")
    _check_width(sigma_time, "sigma_time")
    p = max(k, 1) if degree is None else _check_order(degree, "degree")
    p = min(p, t.size - 1)
    lag = t - t[-1]
    scale = float(np.max(np.abs(lag)))  # lags in [−1, 0] keep the design well conditioned
    u = lag / scale
    weights = np.maximum(np.exp(-0.5 * (lag / sigma_time) ** 2), MIN_WEIGHT)
    design = np.vander(u, p + 1, increasing=True)  # columns u⁰ … uᵖ
    root_w = np.sqrt(weights)[:, None]
    # Weighted least squares: c = (Vᵀ W V)⁻¹ Vᵀ W q, solved via the pseudo-inverse of √W V.
    coeff_map = np.linalg.pinv(root_w * design) * root_w.T  # shape (p+1, n)
    L = np.zeros((k + 1, t.size))
    for d in range(min(k, p) + 1):
        L[d] = factorial(d) * coeff_map[d] / scale**d  # d-th derivative at τ = 0
    return L


def initial_state(q_window, order: int, dt: float, smoothing_sigma: float, *,
                  degree: int | None = None) -> np.ndarray:
    """Motion state at the last sample of a window (SPEC 3 initialisation).

    q is the motion variable over the window (from inverse kinematics, or
    observed directly); value and derivatives come from the Gaussian-weighted
    local polynomial fit of :func:`derivative_operator` at the last sample.

    Parameters
    ----------
    q_window : array_like, shape (n,)
        Motion variable (m or rad) at n consecutive steps, n ≥ 1.
    order : int
        Temporal order k.
    dt : float
        Time step δt (s).
    smoothing_sigma : float
        Gaussian width in samples (the paper used 0.6), > 0.
    degree : int, optional
        Polynomial degree (default max(k, 1)).

    Returns
    -------
    numpy.ndarray, shape (k+1,)
        [q, q⁽¹⁾, …, q⁽ᵏ⁾] in units of q per s^d. A single sample gives that
        sample with zero derivatives.
    """
    k = _check_order(order)
    dt = _check_dt(dt)
    q = np.asarray(q_window, dtype=float).reshape(-1)
    if q.size == 0:
        raise DegenerateFitError("initial_state: the window is empty")
    if q.size == 1:
        x = np.zeros(k + 1)
        x[0] = q[0]
        return x
    _check_width(smoothing_sigma, "smoothing_sigma")
    L = derivative_operator(dt * np.arange(q.size), k, smoothing_sigma * dt, degree)
    return L @ q


def initial_covariance(n: int, order: int, dt: float, smoothing_sigma: float, sigma_obs: float, *,
                       degree: int | None = None) -> np.ndarray:
    """Covariance σ_obs² L Lᵀ of :func:`initial_state` under white observation noise (SPEC 3).

    Parameters
    ----------
    n : int
        Window length (samples), ≥ 2.
    order, dt, smoothing_sigma, degree
        As in :func:`initial_state`.
    sigma_obs : float
        Standard deviation of the observation noise on q (units of q).

    Returns
    -------
    numpy.ndarray, shape (k+1, k+1)
        Positive definite when the fit degree is at least k (n ≥ k+1).
    """
    L = derivative_operator(_check_dt(dt) * np.arange(n), order, _check_width(smoothing_sigma, "smoothing_sigma") * dt,
                            degree)
    P = sigma_obs**2 * (L @ L.T)
    return 0.5 * (P + P.T)
