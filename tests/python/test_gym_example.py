"""The gymnasium example (python/examples/quarter_car_env.py) passes gymnasium's own
environment checker, and its episodes are the FMU's: with no action, the observations are what
a Simulation stepped by hand reads at the same times, and a seed gives the same episode."""

import pathlib
import sys

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")
from gymnasium.utils.env_checker import check_env  # noqa: E402

import fmurunner  # noqa: E402
from fmurunner_helpers import ROOT  # noqa: E402

sys.path.insert(0, str(ROOT / "python" / "examples"))
from quarter_car_env import OBSERVED, QuarterCarEnv  # noqa: E402


def test_gymnasiums_checker_accepts_the_environment():
    env = QuarterCarEnv()
    check_env(env, skip_render_check=True)
    env.close()


def test_an_episode_is_the_fmus_run():
    env = QuarterCarEnv(duration=0.5)
    obs, info = env.reset(seed=7)
    observed = [obs]
    truncated = False
    while not truncated:
        obs, reward, terminated, truncated, _ = env.step(np.zeros(1, dtype=np.float32))
        observed.append(obs)
        assert not terminated and reward <= 0.0
    assert len(observed) == 51
    with fmurunner.Simulation("quarter_car", start_values={"speed": info["speed"]}) as sim:
        expected = [np.asarray(sim.get(OBSERVED), dtype=np.float32)]
        for _ in range(50):
            sim.step(0.01)
            expected.append(np.asarray(sim.get(OBSERVED), dtype=np.float32))
    assert np.array_equal(np.array(observed), np.array(expected))
    # The same seed, the same speed and episode; an action changes it.
    again, info_again = env.reset(seed=7)
    assert info_again["speed"] == info["speed"] and np.array_equal(again, observed[0])
    pushed, *_ = env.step(np.array([0.5], dtype=np.float32))
    assert not np.array_equal(pushed, observed[1])
    env.close()
