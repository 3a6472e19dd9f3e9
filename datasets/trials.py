"""Synthetic measured trials with a hidden effect (for tests, benchmarks and the demo).

A *case* draws, from one seed: an effect from the catalogue (or ``none``) and
its magnitude within the effect's typical range, a trial plan (target final
angles over a range, both directions unless told otherwise, commands from the
ideal model's inverse) and measurement noise; the measured trials are the
simulation with the hidden effect plus Gaussian noise on every angle.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cvmeasure.contracts import TrialTable
from cvmeasure.sim.effects import EFFECT_NAMES, EFFECTS, Effect
from cvmeasure.sim.model import pin_command_for_angle, simulate
from cvmeasure.sim.params import SimParams

__all__ = ["HiddenCase", "draw_effect", "random_plan", "measure_trials", "hidden_case"]


@dataclass(frozen=True)
class HiddenCase:
    """Synthetic trials and the truth hidden in them."""

    trials: TrialTable
    effect: Effect
    noise_deg: float
    seed: int

    def to_dict(self) -> dict[str, Any]:
        return {
            "effect": self.effect.to_dict(),
            "noise_deg": self.noise_deg,
            "seed": self.seed,
            "n_trials": len(self.trials),
        }


def draw_effect(rng: np.random.Generator, name: str | None = None) -> Effect:
    """An effect (drawn from the catalogue, ``none`` included, unless named) of typical size."""
    if name is None:
        name = str(rng.choice(EFFECT_NAMES))
    spec = EFFECTS[name]
    if name == "none":
        return Effect("none")
    lo, hi = spec.typical
    value = float(rng.uniform(lo, hi))
    if spec.signed and rng.random() < 0.5:
        value = -value
    return Effect(name, value)


def random_plan(
    rng: np.random.Generator,
    n_trials: int,
    params: SimParams | None = None,
    *,
    both_directions: bool = True,
    angle_range_deg: tuple[float, float] = (5.0, 130.0),
) -> np.ndarray:
    """Signed pin commands (deg) for random target angles, in random order.

    Directions alternate randomly (half each) when ``both_directions``; commands
    come from the ideal model's inverse and are rounded to 0.1 deg as a
    controller would.
    """
    lo, hi = angle_range_deg
    targets = rng.uniform(lo, hi, n_trials)
    if both_directions:
        signs = np.where(np.arange(n_trials) % 2 == 0, 1.0, -1.0)
        signs = rng.permutation(signs)
    else:
        signs = np.ones(n_trials)
    return np.round(np.asarray(pin_command_for_angle(signs * targets, params)), 1)


def measure_trials(
    commands: np.ndarray,
    effects: tuple[Effect, ...],
    noise_deg: float,
    rng: np.random.Generator,
    params: SimParams | None = None,
    *,
    loaded: bool = True,
    pin: bool = False,
) -> TrialTable:
    """Simulate the plan with the effects and add Gaussian noise (deg) to every angle.

    ``loaded=False`` leaves the loaded angles unmeasured; ``pin=True`` adds the
    pin angle of the loaded photo (machine frame) with the same noise.
    """
    res = simulate(commands, params, effects)
    n = len(commands)
    noisy_loaded = res.loaded_bend_deg + rng.normal(0.0, noise_deg, n)
    noisy_unloaded = res.unloaded_bend_deg + rng.normal(0.0, noise_deg, n)
    if not loaded:
        noisy_loaded = np.full(n, np.nan)
    noisy_pin = res.pin_angle_deg + rng.normal(0.0, noise_deg, n) if pin else None
    return TrialTable.from_arrays(
        commands, noisy_loaded, noisy_unloaded, measured_pin_deg=noisy_pin
    )


def hidden_case(
    seed: int,
    *,
    effect: str | None = None,
    n_trials: int = 60,
    noise_range_deg: tuple[float, float] = (0.03, 0.1),
    both_directions: bool = True,
    loaded: bool = True,
    pin: bool = False,
    params: SimParams | None = None,
) -> HiddenCase:
    """One synthetic case drawn from ``seed`` (effect, magnitude, plan, noise)."""
    rng = np.random.default_rng(seed)
    hidden = draw_effect(rng, effect)
    noise = float(rng.uniform(*noise_range_deg))
    commands = random_plan(rng, n_trials, params, both_directions=both_directions)
    trials = measure_trials(commands, (hidden,), noise, rng, params, loaded=loaded, pin=pin)
    return HiddenCase(trials=trials, effect=hidden, noise_deg=noise, seed=seed)
