"""What a phase of the trainer ``ata_hrl`` uses of the trainer that runs it: the interface the
phases are written against, so that they depend on it and not on the trainer's class."""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
import torch

from ata.plugins.ata_hrl.network import ATAHRLNet
from ata.training import PhaseLoop


class Host(Protocol):
    """The trainer as its phases see it (``ata.plugins.ata_hrl.trainer.ATAHRLTrainer``)."""

    s: Any                                    # the trainer's settings, every phase's group
    registry: Any                             # the components by name
    net: ATAHRLNet
    opt: torch.optim.Optimizer                # pi_C and pi_TR (and the ITA) parameters
    aux_opt: torch.optim.Optimizer
    status_opt: torch.optim.Optimizer | None
    policy_params: list[torch.nn.Parameter]
    device: torch.device                      # where the ITA and CTR phases update
    gen: torch.Generator                      # the policies' sampling
    status_gen: torch.Generator
    loop: PhaseLoop
    trains_ita: bool
    trains_cond: bool
    trains_tr: bool

    @property
    def counters(self) -> dict[str, int]: ...

    def phases(self) -> dict[str, int]: ...

    def mission_of(self, setting: str, seed: int) -> Any: ...

    def setting(self, step: int) -> str: ...

    def ids(self, phase: str, step: int) -> np.ndarray: ...

    def overrides(self, mission: Any, phase: str, recorder: Any, sampler: Any) -> dict: ...

    def rollout(self, mission: Any, ids: np.ndarray, phase: str, train: bool) -> Any: ...

    def validate(self, phase: str) -> tuple[float, dict[str, str]]: ...
