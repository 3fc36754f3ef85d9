"""Train a masked PPO policy on the centralised view of a small team, then compare it with the
built-in `random` and `greedy` policies on held-out scenarios.

Needs the gym extra and two RL libraries that are not dependencies of ata:

    pip install -e '.[gym]' stable-baselines3 sb3-contrib

Usage: python examples/gym_train.py [--minutes 5 | --steps N] [--envs 32] [--eval 200] [--seed 0]

Trains sb3-contrib's MaskablePPO (MultiInputPolicy, observations normalised by VecNormalize) on
`ata.gym.CentralisedVectorEnv` (one batched Simulation for all `--envs` environments, adapted
to Stable-Baselines3's VecEnv below) of examples/missions/gym_small_team.toml, on scenario ids
0, 1, 2, ... Training runs whole rollouts (and their updates) until `--minutes` of wall time
are spent, or until `--steps` environment steps are done (rounded up to whole rollouts of
60 x `--envs` steps). The time-limited run prints its step count: `--steps` with that count and
the same `--seed` trains the same policy again.

Then every method runs the same `--eval` held-out scenarios, ids from
ata.runtime.heldout.EVAL_FIRST_SCENARIO (2**40), far from any id trained on: PPO acting
deterministically under the action masks, `random` (random triples, never reallocated, as
examples/missions/random_baseline.toml) and `greedy` (the mission's own greedy with
reallocation on events) through `ata run`'s runner. It prints each method's mean total points
with a 95% confidence interval, and PPO's paired difference against each baseline.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch


def arguments() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        description=" ".join(__doc__.split("\n\n")[0].split()),
        epilog="Needs: pip install -e '.[gym]' stable-baselines3 sb3-contrib")
    budget = parser.add_mutually_exclusive_group()
    budget.add_argument("--minutes", type=float, default=5.0, help="wall-time training budget")
    budget.add_argument("--steps", type=int, help="environment steps to train (rounded up to whole "
                        "rollouts)")
    parser.add_argument("--envs", type=int, default=32, help="environments stepped together")
    parser.add_argument("--eval", type=int, default=200, help="held-out scenarios")
    parser.add_argument("--seed", type=int, default=0, help="PPO's seed")
    return parser


if __name__ == "__main__":
    ARGS = arguments().parse_args()      # --help answers without the RL libraries

try:
    from sb3_contrib import MaskablePPO
    from stable_baselines3.common.vec_env import VecEnv, VecNormalize
except ModuleNotFoundError as exc:
    raise SystemExit(f"examples/gym_train.py needs {exc.name}: pip install -e '.[gym]' "
                     "stable-baselines3 sb3-contrib") from None

from ata.runtime.heldout import EVAL_FIRST_SCENARIO
from ata.session import load_session
from ata.experiment.runner import mean_ci, run_mission
from ata.gym import CentralisedVectorEnv

MISSION = Path(__file__).resolve().parent / "missions" / "gym_small_team.toml"
BASELINES = {
    "random": ["components.initial='random'", "components.condition='never'",
               "components.reallocation='random'"],
    "greedy": [],
}


class Batched(VecEnv):
    """Stable-Baselines3's VecEnv over `CentralisedVectorEnv`: one kernel call per step for
    every environment. All episodes end together; the step that ends them returns the next
    episodes' first observations, the last ones in ``terminal_observation``, as SB3 expects."""

    def __init__(self, env: CentralisedVectorEnv, n_epochs: int):
        self.env = env
        self.n_epochs = n_epochs
        self._actions: np.ndarray | None = None
        self._masks: np.ndarray | None = None
        super().__init__(env.num_envs, env.single_observation_space, env.single_action_space)

    def reset(self) -> dict[str, np.ndarray]:
        obs, info = self.env.reset()
        self._masks = info["action_mask"]
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, list[dict]]:
        obs, rewards, terminated, truncated, info = self.env.step(self._actions)
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        if dones.all():
            for i, item in enumerate(infos):
                item["terminal_observation"] = {k: v[i] for k, v in obs.items()}
                item["episode"] = {"r": float(info["total"][i]), "l": self.n_epochs}
            obs, info = self.env.reset()
        self._masks = info["action_mask"]
        return obs, rewards.astype(np.float32), dones, infos

    def env_method(self, method_name: str, *args, indices=None, **kwargs) -> list[Any]:
        if method_name != "action_masks":
            raise NotImplementedError(method_name)
        return list(self._masks[self._get_indices(indices)])

    def has_attr(self, attr_name: str) -> bool:
        return attr_name == "action_masks"

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [getattr(self.env, attr_name)] * len(list(self._get_indices(indices)))

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        raise NotImplementedError(attr_name)

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * len(list(self._get_indices(indices)))

    def close(self) -> None:
        self.env.close()


def evaluate_ppo(model: MaskablePPO, norm: VecNormalize, scenarios: int) -> np.ndarray:
    """PPO's total points on the held-out scenarios, acting deterministically under the masks."""
    env = CentralisedVectorEnv(MISSION, num_envs=scenarios,
                               overrides=[f"mission.first_scenario={EVAL_FIRST_SCENARIO}"])
    obs, info = env.reset()
    while True:
        actions, _ = model.predict(norm.normalize_obs(obs), action_masks=info["action_mask"],
                                   deterministic=True)
        obs, _, terminated, _, info = env.step(actions)
        if terminated.all():
            return info["total"]


def main(args: argparse.Namespace) -> None:
    torch.set_num_threads(1)

    session = load_session(str(MISSION))
    n_epochs = session.mission.clock.n_epochs
    norm = VecNormalize(Batched(CentralisedVectorEnv(session, num_envs=args.envs), n_epochs),
                        gamma=1.0)
    model = MaskablePPO("MultiInputPolicy", norm, n_steps=60, batch_size=480, gamma=1.0,
                        ent_coef=0.01, seed=args.seed, verbose=0)
    # one rollout (and its update) at a time, until the budget is spent: a time-limited run and
    # `--steps` with its step count train the same policy
    rollout = model.n_steps * args.envs
    t0 = shown = time.perf_counter()
    while (model.num_timesteps < args.steps if args.steps is not None
           else time.perf_counter() - t0 < 60 * args.minutes):
        model.learn(total_timesteps=rollout, reset_num_timesteps=model.num_timesteps == 0)
        if time.perf_counter() - shown > 30:          # a line every half minute while it trains
            shown = time.perf_counter()
            print(f"  {model.num_timesteps:,} steps, {(shown - t0) / 60:.1f} min", flush=True)
    wall = time.perf_counter() - t0
    steps = model.num_timesteps
    print(f"trained {steps:,} steps ({steps // n_epochs:,} episodes) in "
          f"{wall / 60:.1f} min (reproduce: --steps {steps} --seed {args.seed})")

    norm.training = False
    totals = {"MaskablePPO": evaluate_ppo(model, norm, args.eval)}
    for name, overrides in BASELINES.items():
        session = load_session(str(MISSION), [*overrides, f"mission.scenarios={args.eval}",
                                              f"mission.first_scenario={EVAL_FIRST_SCENARIO}"])
        totals[name] = run_mission(session).total
    print(f"held-out scenarios: {args.eval} (ids from 2**40), total points per scenario")
    for name, values in totals.items():
        mean, half = mean_ci(values)
        print(f"  {name:<12} {mean:8.1f} +- {half:.1f}")
    for name in BASELINES:
        mean, half = mean_ci(totals["MaskablePPO"] - totals[name])
        print(f"  MaskablePPO - {name:<7} {mean:+8.1f} [{mean - half:+.1f}, {mean + half:+.1f}]")


if __name__ == "__main__":
    main(ARGS)
