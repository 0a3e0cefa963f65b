"""Angle traces of a spring-loaded door, pushed open and released (SPEC 8.2).

The paper's recorded door trace is not distributed; this module makes traces
like it from a physical model, per unit moment of inertia (angles in rad,
time in s, torques as angular accelerations in rad/s²):

    θ'' = −ω_n² (θ − θ_spring) − 2 ζ ω_n θ' + a_push(t),

a torsional spring (natural angular frequency ω_n) pulling towards θ_spring,
a viscous damper (damping ratio ζ) and pushes. θ_spring lies below the
closed angle θ_closed, so the spring holds a shut door against the frame.
The frame is a hard stop at θ_closed: a door that reaches it going shut
bounces back with its speed times the restitution e (e = 0: it stops dead;
a rebound slower than ``REST_SPEED`` also ends at rest on the frame).
A push applies a constant a_push from its start time until the door passes
its release angle (or a time limit), then lets go. The motion is integrated
with semi-implicit Euler steps of ``step_s`` and sampled every δt; Gaussian
noise is added to the samples. Everything random comes from the caller's
``numpy.random.Generator``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from stslam.checks import check_fields, check_number

# A rebound slower than this (rad/s) ends in resting contact with the frame, so
# that a preloaded shut door stays exactly at θ_closed instead of chattering.
REST_SPEED = 1e-3


@dataclass(frozen=True)
class DoorModel:
    """Spring, damper and frame stop of the door (SPEC 8.2).

    Attributes
    ----------
    closed_angle : float
        θ_closed, angle of the door shut against the frame (rad).
    spring_rest_angle : float
        θ_spring, where the spring would come to rest without the frame (rad).
    natural_freq : float
        ω_n (rad/s).
    damping_ratio : float
        ζ (dimensionless).
    restitution : float
        e in [0, 1]: speed kept (reversed) on hitting the frame.
    """

    closed_angle: float = 0.6
    spring_rest_angle: float = 0.3
    natural_freq: float = 0.4
    damping_ratio: float = 0.25
    restitution: float = 0.2

    def __post_init__(self):
        check_number("spring_rest_angle", self.spring_rest_angle, high=self.closed_angle)
        check_fields(self, natural_freq="(0, inf)", damping_ratio="[0, inf)", restitution="[0, 1]")


@dataclass(frozen=True)
class Push:
    """One push to open: a_push (rad/s²) from ``start_s`` until θ ≥ ``release_angle`` or ``max_s`` elapsed."""

    start_s: float
    accel: float
    release_angle: float
    max_s: float = 6.0


@dataclass(frozen=True)
class PushJitter:
    """Per-seed variation of the pushes (config ``door.jitter.*``): each start time moves by
    U(−``time_s``, ``time_s``) (s), each push strength is scaled by 1 + U(−``accel_frac``, ``accel_frac``)
    and each release angle moves by U(−``release_rad``, ``release_rad``) (rad)."""

    time_s: float = 1.0
    accel_frac: float = 0.15
    release_rad: float = 0.1


@dataclass(frozen=True)
class DoorScenario:
    """Everything that defines a family of generated traces (config ``door.*``).

    ``pushes`` are the nominal pushes, varied per seed by ``jitter``.
    """

    model: DoorModel
    pushes: tuple[Push, ...]
    n_samples: int = 40
    noise_sigma: float = 0.05
    step_s: float = 0.005
    jitter: PushJitter = PushJitter()


@dataclass(frozen=True)
class DoorTrace:
    """A sampled trace: ``times`` (n,) s, ``angles_true`` (n,) rad, ``angles_observed`` (n,) rad."""

    times: np.ndarray
    angles_true: np.ndarray
    angles_observed: np.ndarray
    pushes: tuple[Push, ...]


def door_angles(times, model: DoorModel, pushes, step_s: float = 0.005) -> np.ndarray:
    """Noise-free door angle θ(t) (rad) at ``times`` (s), starting shut and at rest at t = 0.

    Parameters
    ----------
    times : array_like, shape (n,)
        Non-decreasing sample times, ≥ 0 (s).
    model : DoorModel
    pushes : sequence of Push
    step_s : float
        Integration step (s); sample times are reached to within it.

    Returns
    -------
    numpy.ndarray, shape (n,)
    """
    t_out = np.asarray(times, dtype=float).reshape(-1)
    wn2 = model.natural_freq**2
    c = 2.0 * model.damping_ratio * model.natural_freq
    pushes = sorted(pushes, key=lambda p: p.start_s)
    released = [False] * len(pushes)
    theta, omega, t = model.closed_angle, 0.0, 0.0
    out = np.empty(t_out.size)
    for i, target in enumerate(t_out):
        while t < target - 0.5 * step_s:
            accel = -wn2 * (theta - model.spring_rest_angle) - c * omega  # spring + damper
            for j, push in enumerate(pushes):
                if released[j] or t < push.start_s:
                    continue
                if theta >= push.release_angle or t >= push.start_s + push.max_s:
                    released[j] = True
                else:
                    accel += push.accel
            omega += step_s * accel  # semi-implicit Euler: speed first, then angle
            theta += step_s * omega
            if theta < model.closed_angle:  # the frame: reflect, keep a fraction e of the speed
                theta = model.closed_angle + model.restitution * (model.closed_angle - theta)
                omega = -model.restitution * omega
                if abs(omega) < REST_SPEED:  # too slow to leave the frame: resting contact
                    theta, omega = model.closed_angle, 0.0
            t += step_s
        out[i] = theta
    return out


def jittered_pushes(pushes, rng: np.random.Generator, jitter: PushJitter) -> tuple[Push, ...]:
    """Pushes with start, strength and release moved by uniform draws (one seed's variation)."""
    out = []
    for push in pushes:
        d_time, d_accel, d_release = rng.uniform(-1.0, 1.0, size=3)
        out.append(replace(push,
                           start_s=max(0.0, push.start_s + jitter.time_s * d_time),
                           accel=push.accel * (1.0 + jitter.accel_frac * d_accel),
                           release_angle=push.release_angle + jitter.release_rad * d_release))
    return tuple(out)


def generate_trace(scenario: DoorScenario, dt: float, rng: np.random.Generator) -> DoorTrace:
    """One noisy door trace of ``scenario.n_samples`` samples every ``dt`` s, starting at t = 0."""
    pushes = jittered_pushes(scenario.pushes, rng, scenario.jitter)
    times = dt * np.arange(scenario.n_samples)
    truth = door_angles(times, scenario.model, pushes, scenario.step_s)
    observed = truth + scenario.noise_sigma * rng.standard_normal(truth.size)
    return DoorTrace(times, truth, observed, pushes)

