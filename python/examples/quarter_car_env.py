"""A gymnasium environment over an FMU stepped with fmurunner.Simulation: the quarter car
(models/quarter_car) driving over its sinusoidal road, the disturbance, at a random speed; the
agent's action is ``z_r_dot_ext``, a vertical velocity added to the road's under the tyre (an
active wheel mount, in effect), and the reward is ride comfort: minus the squared body
acceleration. One FMU instance serves every episode: ``reset`` reuses it (``Simulation.reset``),
which is much cheaper than instantiating again.

    env = QuarterCarEnv()
    obs, info = env.reset(seed=1)
    obs, reward, terminated, truncated, info = env.step(np.array([0.0], dtype=np.float32))

Needs gymnasium (``pip install gymnasium``). Checked with gymnasium's own environment checker
in tests/python/test_gym_example.py.
"""

from __future__ import annotations

import os
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

import fmurunner

#: What the agent sees: body and wheel heights and velocities, and the road's height (SI units),
#: with bounds far beyond what the car reaches (its road is a few centimetres high).
OBSERVED = ["z_s", "z_u", "z_s_dot", "z_u_dot", "z_r"]
BOUND = np.array([5.0, 5.0, 50.0, 50.0, 5.0], dtype=np.float32)


class QuarterCarEnv(gym.Env[np.ndarray, np.ndarray]):
    """Quarter car on a sine road; act on ``z_r_dot_ext`` every ``control_step`` seconds for
    ``duration`` seconds (the FMU steps ``control_step`` at a time; it integrates inside)."""

    metadata = {"render_modes": []}

    def __init__(
        self,
        fmu: str | os.PathLike[str] = "quarter_car",
        control_step: float = 0.01,
        duration: float = 2.0,
        speeds: tuple[float, float] = (5.0, 30.0),
        max_action: float = 0.5,
    ) -> None:
        self.sim = fmurunner.Simulation(fmu)
        self.control_step, self.speeds = control_step, speeds
        self.steps = round(duration / control_step)
        self.max_action = max_action
        self.action_space = spaces.Box(-max_action, max_action, shape=(1,), dtype=np.float32)
        self.observation_space = spaces.Box(-BOUND, BOUND, dtype=np.float32)
        self._k = 0

    def _observe(self) -> np.ndarray:
        return np.asarray(self.sim.get(OBSERVED), dtype=np.float32)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        speed = float(self.np_random.uniform(*self.speeds))
        self.sim.reset({"speed": speed})
        self._k = 0
        return self._observe(), {"speed": speed}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        u = float(np.clip(np.asarray(action, dtype=np.float64).reshape(-1)[0], -self.max_action, self.max_action))
        self.sim.set("z_r_dot_ext", u)
        self.sim.step(self.control_step)
        self._k += 1
        acceleration = float(self.sim.get("z_s_ddot"))
        reward = -acceleration * acceleration
        return self._observe(), reward, False, self._k >= self.steps, {"time": self.sim.time}

    def close(self) -> None:
        self.sim.close()
