"""The trainer ``ata_hrl``: trains the ATA-HRL components a training mission's slots hold.

Which parts it trains follows the slots, not names: the ITA policy if the initial slot holds the
``attention`` component, pi_C if the condition slot holds ``ctr``, pi_TR if the reallocation
slot does, the reconstruction if the reconstructors include ``aux``. So the ablations are the
run-time swaps: ``reconstructors = ["identity"]`` trains w/o.AUX, ``condition = "always"`` trains
w/o.C, and an initial-only mission trains the attention ITA alone (AtRL-TR's first stage).

Its phases, in order, each a module of ``ata.plugins.ata_hrl.phases`` with its own settings and
step counter, run by the phase loop of ``ata.training`` (a killed run resumes inside any of
them): aux, status, ita, cond, ctr. ``best.pt`` follows the held-out validation (mean expected
points, decisions by their mode, on validation scenarios of seed ``seed + 1_000_003``).
Checkpoints load with ``torch.load(..., weights_only=True)`` and hold everything needed to
resume.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from threadpoolctl import threadpool_limits

from ata.core.errors import MissionError
from ata.core.kernel import Simulation, build_component
from ata.core.settings import param
from ata.plugins.ata_hrl import decode as D
from ata.plugins.ata_hrl import logprob
from ata.plugins.ata_hrl.checkpoint import (FORMAT, KIND, CheckpointError, check_format,
                                            net_from_checkpoint, read_checkpoint)
from ata.plugins.ata_hrl.components import (AttentionITA, AuxReconstructor, CTRPolicy,
                                            Recorder)
from ata.plugins.ata_hrl.network import ATAHRLNet, NetConfig
from ata.plugins.ata_hrl.phases import FIRST_ID, SPAN, aux, cond, ctr, ita, policy, status
from ata.plugins.ata_hrl.phases.ctr import tr_from_ita
from ata.plugins.ata_hrl.phases.rollouts import Rollouts
from ata.training import VALIDATION_SEED_OFFSET, PhaseLoop, TrainRun, resolve, trained_on

LOG_FIELDS = ["phase", "step", "setting", "episodes", "episodes_per_s", "loss", "mean_score",
              "R_ITA", "R_C", "R_TR", "reallocations", "eval_score", "eval_expected",
              "aux_fatigue_mse", "aux_latency_mse", "wall_s"]
PHASES = ("aux", "status", "ita", "cond", "ctr")


@dataclass
class RunSettings:
    """The keys of ``[ata_hrl]`` that every phase reads."""

    seed: int = param(12345, min=0, max=2**40, help="root seed of the training scenarios "
                      f"(validation uses seed + {VALIDATION_SEED_OFFSET})")
    team_settings: list[str] = param(["a"], choices=("a", "b"), help="team settings trained "
                                     "on, in turn (a mixture when several)")
    uncertainty_levels: list[str] = param([], choices=("none", "low", "medium", "high"),
                                          help="uncertainty levels trained on in turn, crossed "
                                          "with team_settings (step k: the k-th pair, "
                                          "cyclically), and validated on; empty: the mission's "
                                          "level alone")
    batch_size: int = param(16, min=1, max=4096, help="scenarios per step")
    init_from: str = param("", help="start every network from this checkpoint (a path or "
                           "builtin:NAME), its pi_C rule aside, and train on from there "
                           "(another team setting, say)")
    eval_every: int = param(25, min=1, help="held-out validation every N steps")
    eval_scenarios: int = param(64, min=1, max=100_000,
                                help="validation scenarios per team setting (and per "
                                "uncertainty level, with uncertainty_levels); one batch")
    checkpoint_every: int = param(10, min=1, help="write checkpoint.pt every N steps")
    threads: int = param(2, min=1, max=256, help="CPU threads of an ITA step: its rollout's "
                         "episodes in as many processes, its update's parts' gradients side by "
                         "side, each on one torch thread (the weights do not depend on it)")
    device: str = param("cpu", help="torch device of the ITA and CTR phases' updates (the "
                        "log-probabilities, backward and Adam step): 'cpu', or 'cuda' for a GPU; "
                        "the rollouts decode on the CPU, the other phases run there")


@dataclass
class NetSettings:
    """The architecture (NetConfig; a checkpoint records it)."""

    d_model: int = param(32, min=8, max=1024, help="network: embedding width (memory grows)")
    heads: int = param(4, min=1, max=64, help="network: attention heads (scores: POIs^2 each)")
    layers: int = param(2, min=1, max=64, help="network: attention layers (memory grows)")
    hidden: int = param(64, min=4, max=4096, help="network: width of the scorers (memory)")
    z_dim: int = param(4, min=1, max=256, help="network: cVAE latent size (memory grows)")
    recon_hidden: int = param(32, min=4, max=4096,
                              help="network: width of the reconstruction networks (memory)")


@dataclass
class Settings(ctr.Settings, cond.Settings, ita.Settings, policy.Settings, status.Settings,
               aux.Settings, NetSettings, RunSettings):
    """The ``[ata_hrl]`` table: the common keys, the network's, then each phase's in order."""


class ATAHRLTrainer:
    """Trains ATA-HRL's components (see the module's doc)."""

    log_fields = LOG_FIELDS
    Settings = Settings
    presets = {"smoke": {"aux_batches": 1, "aux_steps": 20, "batch_size": 3, "samples": 4,
                         "ita_steps": 6, "ctr_steps": 2, "eval_every": 3, "eval_scenarios": 4,
                         "checkpoint_every": 2}}
    """``ata train --preset smoke``: every phase of the recipe, in seconds on 2 cores."""

    def __init__(self, settings: Settings, mission: Any, registry: Any):
        self.s = settings
        self.mission = mission
        self.registry = registry
        slots = mission.slots
        factory = {slot: registry.get(kind, getattr(slots, slot), "[components]").factory
                   for slot, kind in (("initial", "policy"), ("condition", "condition"),
                                      ("reallocation", "policy"))}
        self.trains_ita = _is(factory["initial"], AttentionITA)
        self.trains_cond = _is(factory["condition"], CTRPolicy)
        self.trains_tr = _is(factory["reallocation"], CTRPolicy)
        self.trains_aux = any(_is(registry.get("reconstructor", n, "").factory,
                                  AuxReconstructor) for n in slots.reconstructors)
        if not (self.trains_ita or self.trains_cond or self.trains_tr):
            raise MissionError("[components]", "initial", "trainer 'ata_hrl' has nothing to "
                               "train: put 'attention' in the initial slot or 'ctr' in the "
                               "condition or reallocation slot", file=mission.source)
        self.cfg = NetConfig(d_model=settings.d_model, heads=settings.heads,
                             layers=settings.layers, hidden=settings.hidden,
                             z_dim=settings.z_dim, recon_hidden=settings.recon_hidden,
                             status_hidden=settings.status_hidden if self.trains_aux else 0)
        self.device = update_device(settings.device, mission.source)
        torch.manual_seed(settings.seed)
        self.net = ATAHRLNet(self.cfg)
        self.policy_params = [p for n, p in self.net.named_parameters()
                              if not n.startswith(("fatigue.", "latency.", "status."))]
        self.opt: torch.optim.Optimizer = torch.optim.Adam(self.policy_params, lr=settings.lr)
        self.aux_opt: torch.optim.Optimizer = torch.optim.Adam(
            list(self.net.fatigue.parameters()) + list(self.net.latency.parameters()),
            lr=settings.aux_lr)
        self.status_opt: torch.optim.Optimizer | None = (
            torch.optim.Adam(self.net.status.parameters(), lr=settings.status_lr)
            if self.cfg.status_hidden else None)
        self.gen = torch.Generator().manual_seed(settings.seed + 1)
        self.status_gen = torch.Generator().manual_seed(settings.seed + 2)
        self.loop = PhaseLoop(PHASES, self.checkpoint)
        self.aux, self.status = aux.AuxPhase(self), status.StatusPhase(self)
        self.ita, self.cond, self.ctr = ita.ItaPhase(self), cond.CondPhase(self), ctr.CtrPhase(self)
        self.rollouts = Rollouts(self, settings.threads)

    # -- the trainer interface ------------------------------------------------------------------
    @property
    def name(self) -> str:
        return getattr(self, "component_name", "ata_hrl")

    @property
    def counters(self) -> dict[str, int]:
        return self.loop.counters

    def scenario_ranges(self) -> list[tuple[int, int, int]]:
        s = self.s
        ranges = [(s.seed, FIRST_ID[p], FIRST_ID[p] + SPAN) for p in FIRST_ID]
        steps = {"aux": s.aux_batches + 1 + self.status.rollouts(s.status_batches + 1),
                 "ita": s.ita_steps, "ctr": s.ctr_steps,
                 "cond": -(-s.cond_scenarios * len(self.cond.pairs()) // s.batch_size)}
        for phase, n in steps.items():
            if n * s.batch_size > SPAN:
                raise MissionError(f"[{self.name}]", "batch_size", f"{phase}: {n} steps of "
                                   f"{s.batch_size} scenarios overrun its range of {SPAN} ids")
        ranges.append((s.seed + VALIDATION_SEED_OFFSET, 0, s.eval_scenarios))
        for other in (s.ita_from, s.init_from):   # what another run's networks saw
            if other:
                ranges += [r for r in trained_on(other, KIND) if r not in ranges]
        return ranges

    def trained_components(self) -> list[str]:
        """The components whose weights best.pt holds (their ``checkpoint`` key names it in the
        run folder's resolved mission)."""
        slots = self.mission.slots
        names = [name for name, trained in ((slots.initial, self.trains_ita),
                                             (slots.condition, self.trains_cond),
                                             (slots.reallocation, self.trains_tr)) if trained]
        if self.trains_aux:
            names += [n for n in slots.reconstructors if _is(
                self.registry.get("reconstructor", n, "").factory, AuxReconstructor)]
        return list(dict.fromkeys(names))

    def phases(self) -> dict[str, int]:
        """The steps of each phase this mission trains (0: none)."""
        s = self.s
        return {"aux": s.aux_steps if self.trains_aux else 0,
                "status": s.status_steps if self.cfg.status_hidden else 0,
                "ita": s.ita_steps if self.trains_ita and not s.ita_from else 0,
                "cond": s.cond_rounds if self.trains_cond and s.cond_scenarios else 0,
                "ctr": s.ctr_steps if (self.trains_cond or self.trains_tr) else 0}

    def total_steps(self) -> int:
        return sum(self.phases().values())

    def done_steps(self) -> int:
        return self.loop.done_steps()

    def run(self, run: TrainRun, resume: bool = False) -> dict[str, Any]:
        """Every phase, resuming wherever the counters stand."""
        self.loop.run = run
        torch.set_num_threads(1)     # one reduction order: `threads` parallels the update's parts
        threadpool_limits(1, user_api="blas")     # the rollouts' products: one thread, as a run's
        if resume and run.resumes:
            self.load(run.checkpoint_path, run.resume_checkpoint(KIND))
        else:
            if self.s.init_from:
                self.take_ita(self.s.init_from, whole=True)
            if self.s.ita_from:
                self.take_ita(self.s.ita_from)
        report: dict[str, float] = {}
        try:
            for part in (self.aux, self.status, self.ita, self.cond, self.ctr):
                report.update(self.loop.run_phase(part.phase()))
        finally:
            self.rollouts.close()
        self._tr_at_step_0()
        return {**self.loop.finish(), "aux": report}

    # -- checkpoints ------------------------------------------------------------------------------
    def checkpoint(self, name: str = "checkpoint.pt") -> dict[str, Any]:
        """Everything to resume from (best.pt and checkpoint.pt alike)."""
        return {"kind": KIND, "format": FORMAT, "model": self.net.state_dict(),
                "config": self.cfg.as_dict(), "optimizer": self.opt.state_dict(),
                "aux_optimizer": self.aux_opt.state_dict(),
                **({"status_optimizer": self.status_opt.state_dict()} if self.status_opt else {}),
                "rng": {"torch": torch.get_rng_state(), "sampler": self.gen.get_state(),
                        "status": self.status_gen.get_state()},
                **self.loop.state(), "mission": self.mission.to_toml(), "trainer": self.name,
                "scenario_ranges": [list(r) for r in self.scenario_ranges()],
                "trained": [k for k, v in (("ita", self.trains_ita), ("cond", self.trains_cond),
                                           ("tr", self.trains_tr), ("aux", self.trains_aux))
                            if v],
                "ita_from": self.s.ita_from, "init_from": self.s.init_from}

    def load(self, path, data: dict[str, Any] | None = None) -> None:
        """Resume from the checkpoint at `path` (its contents `data`, if already read)."""
        data = data if data is not None else read_checkpoint(path, KIND)
        net = net_from_checkpoint(data, path, expect=self.cfg)
        self.net.load_state_dict(net.state_dict())
        try:
            self.opt.load_state_dict(data["optimizer"])
            self.aux_opt.load_state_dict(data["aux_optimizer"])
            if self.status_opt is not None:
                self.status_opt.load_state_dict(data["status_optimizer"])
                self.status_gen.set_state(data["rng"]["status"])
            torch.set_rng_state(data["rng"]["torch"])
            self.gen.set_state(data["rng"]["sampler"])
            self.loop.load_state(data)
        except (KeyError, ValueError, RuntimeError, TypeError) as exc:
            raise CheckpointError(path, f"cannot resume from it ({exc})") from None

    def take_ita(self, spec: str, whole: bool = False) -> None:
        """The ITA network of another ATA-HRL checkpoint (one that trained its ITA), or, with
        `whole`, every network of it but pi_C's rule (which this run's cond phase fits)."""
        path = resolve(spec)
        data = read_checkpoint(path, KIND)
        check_format(data, path)
        if not whole and "ita" not in data.get("trained", []):
            raise CheckpointError(path, "trained no ITA policy (ita_from needs one that did)")
        # the status head's width may differ: this run's status phase trains its own head,
        # unless `whole` takes one of the same width
        mine = {k: v for k, v in self.cfg.as_dict().items() if k != "status_hidden"}
        theirs = {k: v for k, v in (data.get("config") or {}).items() if k != "status_hidden"}
        if theirs != mine:
            raise CheckpointError(path, f"architecture {data.get('config')} does not match "
                                        f"the training's {self.cfg.as_dict()}")
        prefix = "" if whole else "ita."
        part = self.net if whole else self.net.ita
        same_head = self.cfg.status_hidden == (data.get("config") or {}).get("status_hidden")
        skip = ("cond.rule.",) if whole and self.cfg.status_hidden and same_head \
            else ("status.", "cond.rule.")
        weights = {k[len(prefix):]: v for k, v in data["model"].items() if k.startswith(prefix)
                   and not k.startswith(skip)}
        try:
            missing, unexpected = part.load_state_dict(weights, strict=False)
            if unexpected or any(not k.startswith(skip) for k in missing):
                raise RuntimeError(f"missing {missing}, unexpected {unexpected}")
        except RuntimeError as exc:
            raise CheckpointError(path, "its networks do not fit the architecture: "
                                        f"{str(exc).splitlines()[0][:200]}") from None

    def _tr_at_step_0(self) -> None:
        """A run with no CTR step (``ctr_steps = 0``) still ends with pi_TR at the CTR phase's
        step 0, copied from its ITA, in checkpoint.pt and best.pt, as a run with CTR steps
        starts from it."""
        if self.phases()["ctr"] != 0 or not (self.trains_tr or self.trains_cond) \
                or not self.trains_ita:
            return
        tr_from_ita(self.net)
        self.loop.save()
        best = self.loop.run.best_path
        if best.exists():                  # the ITA phase's best step: the same copy in it
            data = read_checkpoint(best, KIND)
            net = net_from_checkpoint(data, best, expect=self.cfg)
            tr_from_ita(net)
            data["model"] = net.state_dict()
            self.loop.run.save(data, "best.pt")

    # -- missions, components, rollouts, validation ---------------------------------------------
    def mission_of(self, setting: str, seed: int):
        """The mission of a step or a validation: `setting` is a team setting, or
        ``SETTING/LEVEL`` with an uncertainty level when ``uncertainty_levels`` mixes them."""
        m = self.mission
        setting, _, level = setting.partition("/")
        if setting != m.settings.setting and m.settings.setting != "custom":
            m = m.replace(setting=setting)          # its sizes follow
        if level:
            m = m.replace(uncertainty=level)        # its variance and probability follow
        return m.replace(seed=seed)

    def cycle(self) -> list[str]:
        """What the steps go through in turn and each validation plays: the team settings,
        each crossed with the uncertainty levels of ``uncertainty_levels`` (``a/high``) if
        any."""
        ts, levels = self.s.team_settings, self.s.uncertainty_levels
        return [f"{t}/{lv}" for lv in levels for t in ts] if levels else list(ts)

    def setting(self, step: int) -> str:
        """The team setting (and level) of a step."""
        ts = self.cycle()
        return ts[step % len(ts)]

    def ids(self, phase: str, step: int) -> np.ndarray:
        """The training scenarios of a phase's step."""
        return FIRST_ID[phase] + step * self.s.batch_size + np.arange(self.s.batch_size)

    def _component(self, mission, slot_kind: str, name: str) -> Any:
        info = self.registry.get(slot_kind, name, "[components]")
        settings = mission.component_settings.get(name)
        if _is(info.factory, (AttentionITA, CTRPolicy, AuxReconstructor)):
            return info.factory(settings, mission, net=self.net)
        return build_component(self.registry, mission, slot_kind, name)

    def overrides(self, mission, phase: str, recorder: Recorder | None,
                  sampler: D.Chooser | None) -> dict[str, Any]:
        """The slots' components for a rollout: the live network in every ATA-HRL part; the
        part(s) the phase trains sample and record. The ITA phase never reallocates and reads
        I alone."""
        slots = mission.slots
        initial = self._component(mission, "policy", slots.initial)
        if phase == "ita":
            if recorder is not None:
                initial.train_with(self.net, recorder, sampler)
            return {"initial": initial,
                    "condition": build_component(self.registry, mission, "condition", "never"),
                    "reallocation": build_component(self.registry, mission, "policy", "keep"),
                    "reconstructors": build_component(self.registry, mission, "reconstructor",
                                                      "identity")}
        out: dict[str, Any] = {"initial": initial}
        both = None
        if self.trains_cond or self.trains_tr:
            both = self._component(mission, "policy", slots.reallocation
                                   if self.trains_tr else slots.condition)
            if recorder is not None and phase == "ctr":
                both.train_with(self.net, recorder, sampler)
        out["condition"] = both if self.trains_cond else \
            self._component(mission, "condition", slots.condition)
        out["reallocation"] = both if self.trains_tr else \
            self._component(mission, "policy", slots.reallocation)
        if self.trains_aux:
            out["reconstructors"] = AuxReconstructor(None, mission, net=self.net)
        return out

    def rollout(self, mission, ids: np.ndarray, phase: str, train: bool):
        """Run scenarios `ids` as the phase plays them: the part it trains sampling and recording
        (`train`), or every decision by its mode."""
        if train and phase == "ita":
            return self.rollouts.ita(mission, ids)
        if not train:
            return self.rollouts.mode(mission, ids, phase), None
        recorder = Recorder()
        overrides = self.overrides(mission, phase, recorder, logprob.torch_sampler(self.gen))
        record = Simulation(mission, self.registry, ids, overrides=overrides).run()
        return record, recorder

    def evaluate(self, phase: str) -> tuple[float, float]:
        """(mean total team performance, its expectation) on the validation scenarios of every
        team setting (and uncertainty level) trained on, each decision by its mode."""
        totals, expected = [], []
        for setting in self.cycle():
            mission = self.mission_of(setting, self.s.seed + VALIDATION_SEED_OFFSET)
            with torch.no_grad():
                record, _ = self.rollout(mission, np.arange(self.s.eval_scenarios), phase,
                                         train=False)
            totals.append(record.total.mean())
            expected.append(record.r_expected.sum(1).mean())
        return float(np.mean(totals)), float(np.mean(expected))

    def validate(self, phase: str) -> tuple[float, dict[str, str]]:
        """The phase loop's validation: best.pt follows the expected points."""
        score, expected = self.evaluate(phase)
        return expected, {"eval_score": f"{score:.2f}", "eval_expected": f"{expected:.2f}"}


def update_device(name: str, source: Any = None) -> torch.device:
    """The device of ``[ata_hrl] device``, refused with a message if torch cannot use it. On a
    GPU, torch's deterministic algorithms are switched on (and cuBLAS's workspace set for
    them), so that a seed gives the same run on the same machine."""
    try:
        device = torch.device(name)
    except RuntimeError:
        device = None
    if device is None or device.type not in ("cpu", "cuda"):
        raise MissionError("[ata_hrl]", "device", f"'{name}' is not a device: use 'cpu' or "
                           "'cuda' (or 'cuda:N')", file=source)
    if device.type == "cuda":
        if not torch.cuda.is_available():
            raise MissionError("[ata_hrl]", "device", f"'{name}': this torch sees no CUDA "
                               "device (a CPU build, or no GPU); use 'cpu'", file=source)
        if device.index is not None and device.index >= torch.cuda.device_count():
            raise MissionError("[ata_hrl]", "device", f"'{name}': this machine has "
                               f"{torch.cuda.device_count()} CUDA device(s)", file=source)
        os.environ.setdefault("CUBLAS_WORKSPACE_CONFIG", ":4096:8")
        torch.use_deterministic_algorithms(True, warn_only=True)
    return device


def _is(factory: Any, cls: type | tuple[type, ...]) -> bool:
    return isinstance(factory, type) and issubclass(factory, cls)
