"""Gymnasium and PettingZoo adapters (the ``gym`` extra: ``pip install -e '.[gym]'``).

- `make` / ``gymnasium.make("ata/Centralised-v0", mission=...)``: the centralised view, one
  scenario at a time (`CentralisedEnv`);
- `make_vec` / ``gymnasium.make_vec("ata/Centralised-v0", num_envs=N, mission=...)``: N
  scenarios in one batched `Simulation` (`CentralisedVectorEnv`);
- `parallel_env`: the decentralised view, one PettingZoo agent per team member
  (`DecentralisedParallelEnv`; imports PettingZoo, and torch for TR-POMDP's agent model).

Nothing in ``ata`` imports this package: ``import ata`` and ``ata run`` never load gymnasium.
The id is registered when this package is imported; ``gymnasium.make("ata.gym:ata/Centralised-v0",
...)`` imports it first. docs/gym.md describes the spaces, the action encoding and the masks.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

try:
    import gymnasium
except ModuleNotFoundError as exc:        # the extra is not installed: say how to get it
    raise ModuleNotFoundError(
        f"ata.gym needs the gym extra ({exc.name} is not installed): pip install 'ata[gym]' "
        "(from a checkout: pip install -e '.[gym]')", name=exc.name) from None

from ata.session import Session
from ata.gym.centralised import CentralisedEnv, CentralisedVectorEnv, sample_masked

if TYPE_CHECKING:
    from ata.gym.decentralised import DecentralisedParallelEnv

ENV_ID = "ata/Centralised-v0"
"""The registered id of the centralised view."""

gymnasium.register(id=ENV_ID, entry_point="ata.gym.centralised:CentralisedEnv",
                   vector_entry_point="ata.gym.centralised:CentralisedVectorEnv")


def make(mission: str | Path | Session | None = None, *,
         overrides: Sequence[str] = ()) -> CentralisedEnv:
    """The centralised view of a mission file (None: the greedy reference mission), one
    scenario at a time; `overrides` as ``ata run --set``."""
    return CentralisedEnv(mission, overrides=overrides)


def make_vec(mission: str | Path | Session | None = None, *, num_envs: int = 8,
             overrides: Sequence[str] = ()) -> CentralisedVectorEnv:
    """The centralised view of `num_envs` scenarios stepped together in one `Simulation`."""
    return CentralisedVectorEnv(mission, num_envs=num_envs, overrides=overrides)


def parallel_env(mission: str | Path | Session | None = None, *,
                 overrides: Sequence[str] = (), k: int = 4) -> "DecentralisedParallelEnv":
    """The decentralised view: a PettingZoo ``ParallelEnv`` with one agent per human and robot
    (TR-POMDP's agents, `k` candidate POIs each)."""
    from ata.gym.decentralised import DecentralisedParallelEnv   # the extra's pettingzoo
    return DecentralisedParallelEnv(mission, overrides=overrides, k=k)


def __getattr__(name: str) -> Any:
    """`DecentralisedParallelEnv`, imported (with PettingZoo) when first asked for."""
    if name == "DecentralisedParallelEnv":
        from ata.gym.decentralised import DecentralisedParallelEnv   # the extra's pettingzoo
        return DecentralisedParallelEnv
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = ["ENV_ID", "CentralisedEnv", "CentralisedVectorEnv", "DecentralisedParallelEnv",
           "make", "make_vec", "parallel_env", "sample_masked"]
