"""A suite's method of published rows (``mission = "published:METHOD"``): a backend whose
batches are read from a published set, never run (`ata.backend`)."""

from __future__ import annotations

import json
import tempfile
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ata import __version__
from ata.backend import IN_PROCESS, OnEpoch, Part, Quiet
from ata.core.errors import MissionError
from ata.core.mission import Mission, parse_override
from ata.core.registry import Register
from ata.runtime.inputs import read_json_object
from ata.published.sets import (DEFAULT, MANIFEST, PREFIX, PUBLISHED, Results, cell_name,
                                read_published, release, set_name, shown, world_digest)
from ata.session import Session, load_session

_ROWS_READ: dict[Path, Results] = {}


class PublishedRows(Quiet):
    """The rows of one method of a published set (`folder`, `method`), as a backend: its
    session is the published resolved mission of the cell an evaluation asks for, checked
    against the code and weights installed now; its batches are the published rows."""

    label = "published rows"

    def __init__(self, folder: Path, method: str):
        self.folder, self.method = Path(folder), method

    @property
    def source(self) -> str:
        """How its mission's source names it: ``published:NAME:METHOD`` for a shipped set,
        else ``published:FOLDER:METHOD`` (FOLDER relative to the working folder where it is
        under it): no path of this machine in a message."""
        label = shown(self.folder)
        return f"{label if label.startswith(PREFIX) else PREFIX + label}:{self.method}"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, PublishedRows) and (other.folder, other.method) == \
            (self.folder, self.method)

    def __hash__(self) -> int:
        return hash((self.folder, self.method))

    def key(self) -> dict[str, Any]:
        return {"published": f"{PREFIX}{self.folder}:{self.method}"}

    def registry(self, raw: dict[str, Any], optional: list[str], source: str,
                 extra: tuple = ()) -> tuple[Register, dict[str, Any]]:
        return IN_PROCESS.registry(raw, optional, source, extra)

    def check(self, mission: Mission, registry: Register,
              inspect: Callable[[Any], None]) -> None:
        pass                             # checked as read (`load`); nothing is built

    def worker_registry(self, mission: Mission) -> None:
        return None

    def _manifest(self) -> dict[str, Any]:
        return json.loads((self.folder / MANIFEST).read_text(encoding="utf-8"))

    def _entry(self) -> dict[str, Any]:
        return self._manifest()["methods"][self.method]

    def load(self, overrides: list[str]) -> Session:
        """The session of the method at the cell the evaluation's `overrides` choose (its
        published resolved mission, with the evaluation's scenarios and seed), checked: its
        scenarios among the published ones, its code and weights the installed ones."""
        method, manifest = self.method, self._manifest()
        entry = manifest["methods"][method]
        if release(manifest) != __version__:
            raise MissionError("", None, f"published {method} is of the set "
                               f"{set_name(self.folder, manifest)} ({shown(self.folder)}), made "
                               f"with ata {release(manifest)}; this is ata {__version__}: rows "
                               "of two releases are not paired; evaluate the method itself "
                               f"instead, or read a set published with ata {__version__}")
        keys = {tuple(parse_override(t)[0]): parse_override(t)[1] for t in overrides}
        setting, level = keys.get(("mission", "setting")), keys.get(("mission", "uncertainty"))
        cells = entry["cells"]
        if setting is None or level is None:
            if len(cells) != 1:
                raise MissionError("", None, f"published {method} has rows at "
                                   f"{', '.join(cells)}: give the suite's settings and "
                                   "uncertainty")
            setting, level = next(iter(cells)).split("/")
        info = cells.get(cell_name(setting, level))
        if info is None:
            raise MissionError("", None, f"published {method} has no rows at setting "
                               f"{setting}, {level} uncertainty; it has: {', '.join(cells)}")
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "mission.toml"
            path.write_text(info["mission"], encoding="utf-8")
            session = load_session(str(path), [t for t in overrides if parse_override(t)[0][1]
                                               in ("scenarios", "seed", "first_scenario")],
                                   backend=self)
        m = session.mission
        m.source = self.source
        first, count = info["scenarios"]
        lo, hi = m.settings.first_scenario, m.settings.first_scenario + m.settings.scenarios
        if str(m.seed_label) != str(info["seed"]) or lo < first or hi > first + count:
            raise MissionError("", None, f"published {method} ({setting}, {level}) holds seed "
                               f"{info['seed']}, ids {first}..{first + count - 1}; the "
                               f"evaluation asks for seed {m.seed_label}, ids {lo}..{hi - 1}: "
                               "give the published seed and at most its scenarios")
        code, weights = session.code(), session.inputs()
        changed = [k for k, v in entry.get("code", {}).items() if code.get(k) not in (None, v)]
        changed += [k for k, v in info.get("inputs", {}).items() if weights.get(k) != v]
        if changed:
            raise MissionError("", None, f"the published rows of {method} were made with other "
                               f"code or weights than are installed now ({', '.join(changed)}):"
                               " evaluate the method itself instead")
        return session

    def model(self, setting: str, level: str) -> str:
        """The model revision of the method's rows at a cell."""
        return self._entry()["cells"][cell_name(setting, level)]["model"]

    def run_batch(self, mission: Mission, registry: Register | None, ids: np.ndarray,
                  on_epoch: OnEpoch | None = None) -> Part:
        """The batch's rows read from the set, in the order of `ids`; nothing is run."""
        if self.folder not in _ROWS_READ:
            _ROWS_READ[self.folder] = read_published(self.folder)[0]
        rows = _ROWS_READ[self.folder]
        c = rows.columns
        sel = np.nonzero(rows.select(self.method, mission.settings.setting,
                                     mission.settings.uncertainty))[0]
        where = {int(c["scenario"][k]): k for k in sel}
        missing = [int(i) for i in ids if int(i) not in where]
        if missing:
            raise MissionError("", None, f"published {self.method} has no row for scenario "
                               f"{missing[0]}: publish it again from the evaluation "
                               "(ata publish EVAL_DIR -o DIR)", file=shown(self.folder))
        pick = np.array([where[int(i)] for i in ids], dtype=np.int64)
        out: Part = {"scenario": np.asarray(ids), "total": c["score"][pick].astype(float),
                     "upper_bound": c["upper_bound"][pick].astype(float),
                     "reallocations": c["reallocations"][pick].astype(np.int64)}
        for name, values in c.items():
            if name in ("method", "setting", "uncertainty", "scenario", "seed", "score",
                        "upper_bound", "fraction_of_u", "reallocations"):
                continue
            column = values[pick].astype(float)
            if not np.all(np.isnan(column)):      # a metric another method has, this one not
                out[f"m:{name}"] = column
        out["warnings"] = []
        for epoch in range(mission.clock.n_epochs if on_epoch is not None else 0):
            on_epoch(epoch)                        # the progress bar counts it done
        out["wall_s"] = 0.0
        return out


def published_method(spec: str, base: Path, where: str, path: str) -> PublishedRows:
    """A suite's ``published:METHOD`` (the default set) or ``published:SET:METHOD`` (a shipped
    set, or a folder relative to the suite file) as the backend of its rows."""
    name, _, method = spec.split(":", 1)[1].rpartition(":")
    candidates = [PUBLISHED / (name or DEFAULT)] + ([base / name, Path(name).expanduser()]
                                                    if name else [])
    folder = next((c for c in candidates if (c / MANIFEST).is_file()), None)
    if folder is None:
        shipped = sorted(p.parent.name for p in PUBLISHED.glob(f"*/{MANIFEST}"))
        raise MissionError(where, "mission", f"{spec!r}: no published rows "
                           f"{name or DEFAULT!r}; shipped sets: "
                           f"{', '.join(shipped) or '(none in this version yet)'}; or "
                           "published:FOLDER:METHOD, a folder that `ata publish` wrote",
                           file=path)
    manifest = read_json_object(folder / MANIFEST, "the manifest of published rows")
    if method not in manifest.get("methods", {}):
        raise MissionError(where, "mission", f"{spec!r}: the published rows in {shown(folder)} "
                           f"hold no method {method!r}; name one they hold: "
                           + ", ".join(manifest.get("methods", {})), file=path)
    return PublishedRows(folder.resolve(), method)


def check_models(jobs: list[Any]) -> None:
    """Refuse an evaluation whose methods run in another model than a published method they
    are paired with in the same (setting, level)."""
    for pub in jobs:
        rows = pub.session.backend
        if not isinstance(rows, PublishedRows):
            continue
        model = rows.model(pub.setting, pub.level)
        for job in jobs:
            if isinstance(job.session.backend, PublishedRows) or \
                    (job.setting, job.level) != (pub.setting, pub.level):
                continue
            mine = world_digest(job.mission.resolved(), job.session.code())
            if mine != model:
                raise MissionError(f"method {job.method!r}", None, f"runs in another model than "
                                   f"the published {rows.method} ({job.setting}, {job.level}): "
                                   f"model revision {mine} here, {model} there (the world "
                                   "components' code or settings, or the team, clock or "
                                   "uncertainty, differ); the rows cannot be paired: run "
                                   "it in the published method's world (its resolved mission "
                                   "is in the set's manifest.json) or evaluate "
                                   f"{rows.method} itself beside it",
                                   file=job.source)
