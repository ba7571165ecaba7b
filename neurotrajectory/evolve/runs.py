"""Training runs: the generation loop, the run directory, checkpoints and resuming.

A run directory holds ``README.md`` (its files and the command that made it),
``config.json`` (the resolved configuration), ``checkpoint.npz``
(the last complete generation: its population and fitness, written atomically),
``history.json`` (every generation's fitness vectors, Pareto ranks, hypervolume, timing and,
with validation episodes, its knee's validation score: the learning curve),
``warm_start.npz`` (the warm start's genome, generation 0's parent, if the run has one),
``front.npz`` / ``front.json`` (the final Pareto front: weights and fitness) and ``plots/``.
A resumed run continues after the last complete generation and gives the same result as an
uninterrupted run with the same seed.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
import time
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any, ClassVar

import numpy as np
from pydantic import BeforeValidator, Field, model_validator
from tqdm import tqdm

from gridsim.errors import GridSimError, flagged, warn_data
from gridsim.outputs import (
    counted,
    empty_folder,
    folder_lock,
    new_folder_problem,
    output_problem,
    progress_bar,
    read_manifest,
    write_json,
    write_npz,
    write_text,
)
from gridsim.scenario.schema import MAX_DURATION
from gridsim.seeding import Salt, stream
from neurotrajectory.data.storage import dataset_manifest, load_dataset
from neurotrajectory.data.windows import (
    DAGGER_LABELS,
    GENERATED_STRIDE,
    RECORDED_STRIDE,
    DatasetError,
    Windows,
    drive_windows,
    episodes_of,
    goal_overrides,
    has_recorded,
    is_recorded,
    recording_mismatch,
    scenario_episodes,
)
from neurotrajectory.evolve.backends import BACKENDS, WorkerSpec, make_backend
from neurotrajectory.evolve.evolution import (
    ANCHOR,
    SELECTIONS,
    GAConfig,
    anchored_violation,
    es_centre,
    es_recipes,
    generation_rng,
    initial_recipes,
    next_generation,
    warm_start_recipes,
)
from neurotrajectory.evolve.fitness import net_config_for, scenario_net_config
from neurotrajectory.evolve.genome import genome_mismatch, initial_genome, set_genome, table_size
from neurotrajectory.evolve.pareto import (
    generation_hypervolume,
    hypervolume,
    minimised,
    non_dominated_sort,
    pick_member,
)
from neurotrajectory.evolve.population import Population, Source, Start
from neurotrajectory.model import (
    ACTIVATIONS,
    EVOLVE_SCOPES,
    FRAMES,
    PRESETS,
    PRIORS,
    NetConfig,
    NetPolicy,
    TrajectoryNet,
    checked_max_correction,
    size_mismatch,
)
from neurotrajectory.settings import Bool, Integer, OneOf, Real, Seed, Settings

FORMAT_VERSION = 2  # 1: before frame, skip and pretrain_validation
PRETRAIN_EPISODE_SECONDS = 30.0  # length of the episodes recorded for a warm start [s]
WARM_START_FILE = "warm_start.npz"  # the warm start's genome in a run folder
#: the warm start's fit while it runs, saved after each epoch (an interrupted fit goes on;
#: runs without DAgger rounds)
WARM_START_FIT_FILE = "warm_start_fit.pt"
#: The SHA-256 of the files the run's scenario is read from when it began (resumes check them).
INPUTS_FILE = "inputs.json"


def code_digest() -> dict[str, str]:
    """The code a run is trained by: the package's version and a SHA-256 of the Python
    sources of ``gridsim`` and ``neurotrajectory`` (a resume with other code goes on with
    another algorithm: its result is then neither code's uninterrupted run)."""
    import gridsim
    import neurotrajectory

    h = hashlib.sha256()
    for package in (gridsim, neurotrajectory):
        root = Path(package.__file__).resolve().parent
        for f in sorted(root.rglob("*.py")):
            name = f.relative_to(root.parent)
            # (an editor's lock file, a notebook's checkpoint: not the package's code)
            if any(part.startswith(".") for part in name.parts) or not f.is_file():
                continue
            try:
                text = f.read_bytes().replace(b"\r\n", b"\n")  # (a Windows checkout's)
            except OSError:
                continue
            h.update(name.as_posix().encode() + b"\0" + text)
    return {"version": gridsim.__version__, "sources": h.hexdigest()[:16]}


#: Runs with a warm start: the best validated knee of any generation.
BEST_KNEE_FILE = "best_knee.npz"


class RunError(RuntimeError):
    """A run directory is missing, corrupt or incompatible with the requested run."""


class SettingsClash(RunError):
    """:meth:`Run.open` was asked for settings that would change the run's results:
    ``clash`` maps each such :class:`TrainConfig` field to ``(the run's value, the value
    asked)`` (a command line names its flags instead)."""

    def __init__(self, out: Path, clash: dict[str, tuple[Any, Any]]) -> None:
        self.out, self.clash = out, clash
        detail = ", ".join(f"{k}: run has {a!r}, asked {b!r}" for k, (a, b) in clash.items())
        super().__init__(f"{out}: cannot resume with a different configuration ({detail})")


#: The largest mutation step accepted (``sigma``): larger ones overflow the network's
#: weights (the recipes use 0.02 to 0.1).
MAX_SIGMA = 10.0

#: The largest ``es_step`` accepted (the centre would leap past its pairs' noise).
MAX_ES_STEP = 100.0


def _names(tracks: Any) -> Any:
    """Track ids as names (``ego_tracks`` may be given as integers, in any collection: a
    list, a tuple, a NumPy array, a range); a single string is left to be refused."""
    if isinstance(tracks, str | bytes) or not isinstance(tracks, Iterable):
        return tracks
    return tuple(str(t) for t in tracks)


def _bound(bound: Any) -> tuple[float, float] | None:
    """``max_correction`` as two floats [m] (``config.json`` stores a list)."""
    if bound is None:
        return None
    return checked_max_correction(bound, "ego")  # the frame is checked with the others


class TrainConfig(Settings):
    """Everything that determines a run (saved as ``config.json``). Each field's description
    is its ``train`` flag's help. ``activation`` and ``selection`` given as None are stored
    resolved (from the preset; from whether there is a warm start)."""

    Error: ClassVar[type[Exception]] = RunError

    scenario: str = Field("seamless", description="built-in name, YAML path, or a "
                          "comma-separated list, folder or glob of them")  # fmt: skip
    preset: Annotated[str, OneOf(PRESETS)] = Field("default", description="network size")
    population: Annotated[Integer, Field(ge=2)] = Field(16, description="networks per generation")
    generations: Annotated[Integer, Field(ge=1)] = Field(10, description="generations to evolve")
    episodes: Annotated[Integer, Field(ge=1)] = Field(
        2, description="evaluation episodes per individual"
    )
    episode_seconds: Annotated[Real, Field(gt=0, le=MAX_DURATION)] = Field(
        15.0, description="length of each training episode [s]"
    )
    sigma: Annotated[Real, Field(gt=0, le=MAX_SIGMA)] = Field(
        GAConfig.sigma, description="mutation noise scale (the standard deviation per weight; "
        "larger than 10 overflows the network's weights)")  # fmt: skip
    elite_fraction: Annotated[Real, Field(gt=0, lt=1)] = Field(
        GAConfig.elite_fraction, description="share of each generation kept as parents"
    )
    seed: Seed = Field(0, description="seed of the whole run")
    backend: Annotated[str, OneOf(BACKENDS)] = Field(
        "local", description="where individuals are evaluated"
    )
    workers: Annotated[Integer, Field(ge=1)] = Field(
        2, description="worker processes or Ray actors"
    )
    batch: Annotated[Integer, Field(ge=1)] = Field(
        16, description="individuals each worker evaluates together (does not change results)"
    )
    ray_address: str | None = Field(
        None, description="an existing Ray cluster (default: start a local one)"
    )
    pretrain: str | None = Field(
        None, description="first fit the network to the windows of this recorded dataset"
    )
    pretrain_episodes: Annotated[Integer, Field(ge=0)] = Field(
        0, description="first fit the network to N episodes of the scenario recorded now (30 s "
        "each, training seeds; generated scenarios only)")  # fmt: skip
    pretrain_epochs: Annotated[Integer, Field(ge=1)] = Field(
        20, description="epochs of the warm start's fit"
    )
    prior: Annotated[str, OneOf(PRIORS)] | None = Field(
        None, description=f"the kinematic prior the network refines (default: the preset's, "
        f"{NetConfig.prior})")  # fmt: skip
    resample_episodes: Bool = Field(
        True, description="new episode seeds every generation (else the same for all)"
    )
    constrained: Bool = Field(
        True, description="collisions and leaving the road rank below any fitness"
    )
    validation_episodes: Annotated[Integer, Field(ge=0)] = Field(
        8, description="choose the final front on N more training episodes (0: the last "
        "generation's)")  # fmt: skip
    frame: Annotated[str, OneOf(FRAMES)] = Field(
        "ego", description="frame of the network's residual on its prior: 'ego', along and "
        "across the heading, or 'grid'")  # fmt: skip
    skip: Bool = Field(True, description="the linear read-out of the ego's kinematic features")
    pretrain_validation: Annotated[Real, Field(ge=0, lt=1)] = Field(
        0.2, description="share of the warm start's tracks held out to pick its epoch (0: keep "
        "the last epoch)")  # fmt: skip
    ego_tracks: Annotated[tuple[str, ...], BeforeValidator(_names)] = Field(
        (), description="recorded scenes: the tracks the episodes drive as the ego (empty: any; "
        "with pretrain data on a recorded scene, Run.create sets the data's tracks of that "
        "scene)")  # fmt: skip
    dagger_rounds: Annotated[Integer, Field(ge=0)] = Field(
        0, description="after the warm start, N rounds of driving the fitted network on its "
        "episodes and refitting it to the states it visited (DAgger), labelled as dagger_labels "
        "says")  # fmt: skip
    dagger_weight: Annotated[Real, Field(gt=0)] | None = Field(
        None,
        description="the DAgger windows' total weight in the refit as a share of the "
        "human windows' (default: every window weighs alike, however many were visited)",
    )
    dagger_labels: Annotated[str, OneOf(DAGGER_LABELS)] = Field(
        "rejoin", description="how the DAgger windows are labelled: 'rejoin', the human's path "
        "shifted by the ego's offset from the human, the shift fading out over the horizon; "
        "'human', the human's next set-points from there")  # fmt: skip
    evolve: Annotated[str, OneOf(EVOLVE_SCOPES, "evolve scope")] = Field(
        "all",
        description="what mutation changes: 'all' weights, or with a warm start only the "
        "planning 'head' (LSTM branches and read-outs) or only the linear 'readout's",
    )
    activation: Annotated[str, OneOf(ACTIVATIONS)] | None = Field(
        None, description=f"the network's hidden activation (default: the preset's, "
        f"{NetConfig.activation})")  # fmt: skip
    plan_smoothing: Annotated[Real, Field(ge=0, lt=1)] = Field(
        0.7,
        description="in closed loop (training, held-out episodes, evaluation, videos), "
        "keep this share of the previous plan in each new one (0: follow every plan as given)",
    )
    selection: Annotated[str, OneOf(SELECTIONS)] | None = Field(
        None, description="how parents are selected: 'anchored' (the default with a warm "
        "start): the warm start stays in every generation and a member whose l1 is worse than "
        "its is ranked as a constraint violation; 'es': evolution strategies, a centre (first "
        "the warm start) and antithetic pairs around it, the centre moved by their "
        "rank-weighted noise (es_step); 'pareto' (the default without): constrained NSGA-II on "
        "the three objectives")  # fmt: skip
    es_step: Annotated[Real, Field(gt=0, le=MAX_ES_STEP)] = Field(
        3.0, description="selection 'es': how far the centre moves per generation, in mean noise "
        "steps of its pairs (3 chosen on the main job's development seeds)")  # fmt: skip
    goal_seconds: Annotated[Real, Field(gt=0)] | None = Field(
        None,
        description="how far ahead the destination the network is given lies [s] (the "
        "scenario's env.goal_seconds; default the scenario's, the last set-point's time)",
    )
    max_correction: Annotated[tuple[float, float] | None, BeforeValidator(_bound)] = Field(
        None, description="bound the network's correction to its prior to these many metres "
        "along and across the heading (tanh-squashed; default: unbounded)")  # fmt: skip
    validation_tracks: Annotated[Real, Field(ge=0, lt=1)] = Field(
        0.0, description="recorded scenes: keep this share of the training tracks out of "
        "evolution and draw the validation episodes from them (0: the validation episodes "
        "drive the training tracks)")  # fmt: skip

    #: Fields left out of the run's fingerprint while at these values: added after runs were
    #: saved, with these values meaning what those runs did.
    UNSTAMPED_DEFAULTS: ClassVar[dict] = {"max_correction": None, "validation_tracks": 0.0}
    #: What format-1 configurations (saved before these fields existed) meant.
    LEGACY: ClassVar[dict] = {"frame": "grid", "skip": False, "pretrain_validation": 0.0,
                              "dagger_labels": "human", "plan_smoothing": 0.0,
                              "selection": "pareto"}  # fmt: skip
    #: Fields added within format 2, and what a format-2 configuration without them meant.
    LATER: ClassVar[dict] = {"dagger_labels": "human", "plan_smoothing": 0.0,
                             "selection": "pareto", "es_step": 3.0}  # fmt: skip
    #: Fields that may differ between a run and its resumption (they do not change results).
    RESUMABLE: ClassVar[tuple] = ("generations", "backend", "workers", "ray_address", "batch")

    @model_validator(mode="before")
    @classmethod
    def _resolve(cls, data: Any) -> Any:
        """The activation (from the preset) and the selection (from the warm start) where
        None: stored resolved."""
        if not isinstance(data, dict):
            return data
        data = dict(data)
        preset = data.get("preset", cls.model_fields["preset"].default)
        if data.get("activation") is None and isinstance(preset, str) and preset in PRESETS:
            data["activation"] = PRESETS[preset].activation
        if data.get("selection") is None:
            warm = bool(data.get("pretrain") or data.get("pretrain_episodes"))
            data["selection"] = "anchored" if warm else "pareto"
        return data

    @model_validator(mode="after")
    def _together(self) -> TrainConfig:
        """The checks across fields (each field was valid on its own)."""
        warm = self.warm_started
        problems = []
        if self.pretrain and self.pretrain_episodes:
            problems.append("give either --pretrain (a dataset) or --pretrain-episodes, not both")
        if self.dagger_rounds and not warm:
            problems.append("--dagger-rounds refit the warm start: give --pretrain or "
                            "--pretrain-episodes")  # fmt: skip
        if self.dagger_weight is not None and not self.dagger_rounds:
            problems.append(f"--dagger-weight {self.dagger_weight:g} weighs the DAgger rounds' "
                            "windows: give --dagger-rounds >= 1")  # fmt: skip
        if self.pretrain_episodes == 1 and self.pretrain_validation > 0:
            problems.append("--pretrain-episodes 1 leaves no episode to validate the warm start "
                            "on: record >= 2 or set --pretrain-validation 0")  # fmt: skip
        if self.validation_tracks and self.ego_tracks and not self.held_tracks:
            problems.append(f"--validation-tracks {self.validation_tracks:g} needs a scene with "
                            "at least 2 training tracks to split, got "
                            f"{list(self.ego_tracks)}")  # fmt: skip
        if self.validation_tracks and not self.validation_episodes:
            problems.append(
                f"--validation-tracks {self.validation_tracks:g} holds tracks out "
                "for the validation episodes: give --validation-episodes >= 1"
            )
        if self.evolve != "all" and not warm:
            problems.append(f"--evolve {self.evolve} keeps the warm start's encoder: give "
                            "--pretrain or --pretrain-episodes, or --evolve all")  # fmt: skip
        if self.anchored and not warm:
            problems.append(f"--selection {self.selection} starts from the warm start and "
                            "keeps a member no worse than it: give --pretrain or "
                            "--pretrain-episodes, or --selection pareto")  # fmt: skip
        if self.max_correction is not None:
            try:
                checked_max_correction(self.max_correction, self.frame)
            except ValueError as exc:
                problems.append(str(exc))
        if problems:
            count = f"{len(problems)} problems: " if len(problems) > 1 else ""
            raise ValueError(count + "; ".join(problems))
        return self

    @property
    def warm_started(self) -> bool:
        """Generation 0 is made from a network fitted to human windows first (a dataset,
        ``pretrain``, or ``pretrain_episodes`` recorded now)."""
        return bool(self.pretrain or self.pretrain_episodes)

    @property
    def anchored(self) -> bool:
        """Individual 0 is kept in every generation (the warm start; with evolution
        strategies, the centre) and its l1 is a constraint."""
        return self.selection in ("anchored", "es")

    @property
    def es(self) -> bool:
        """Evolution strategies: a centre and antithetic pairs around it."""
        return self.selection == "es"

    @property
    def ga(self) -> GAConfig:
        return GAConfig(
            population=self.population, elite_fraction=self.elite_fraction, sigma=self.sigma
        )

    @property
    def net(self) -> NetConfig:
        """The preset's network with the configured frame, skip read-out, activation, plan
        smoothing and prior."""
        base = replace(PRESETS[self.preset], frame=self.frame, skip=self.skip,
                       activation=self.activation, smoothing=self.plan_smoothing,
                       max_correction=self.max_correction)  # fmt: skip
        return base if self.prior is None else replace(base, prior=self.prior)

    def episode_seeds(self, generation: int) -> tuple[int, ...]:
        """The episodes (scenario seeds) of ``generation``, the same for every individual:
        drawn anew each generation (``resample_episodes``) or the same for all. Training
        seeds are even; :meth:`heldout_seeds` are odd, so never used in training."""
        salt = [generation] if self.resample_episodes else []
        rng = stream(self.seed, Salt.EPISODES, *salt)
        return tuple(2 * int(s) for s in rng.integers(0, 2**30 - 1, size=self.episodes))

    @property
    def pretrain_seeds(self) -> tuple[int, ...]:
        """The episodes recorded for the warm start (``pretrain_episodes``): training seeds
        (even), none of them a generation's or a validation episode."""
        rng = stream(self.seed, Salt.PRETRAIN_EPISODES)
        return tuple(2 * int(s) for s in rng.integers(0, 2**30 - 1, size=self.pretrain_episodes))

    @property
    def validation_seeds(self) -> tuple[int, ...]:
        """The episodes the final front is chosen on: training seeds (even) that no
        generation was evaluated on."""
        rng = stream(self.seed, Salt.VALIDATION_EPISODES)
        return tuple(2 * int(s) for s in rng.integers(0, 2**30 - 1, size=self.validation_episodes))

    def heldout_seeds(self, count: int) -> tuple[int, ...]:
        """``count`` episode seeds that no generation trains on (odd numbers)."""
        rng = stream(self.seed, Salt.HELDOUT_EPISODES)
        return tuple(2 * int(s) + 1 for s in rng.integers(0, 2**30 - 1, size=count))

    @property
    def held_tracks(self) -> tuple[str, ...]:
        """The training tracks kept out of evolution to validate on, or none: of each scene's
        tracks in ``ego_tracks`` (``SCENE/ID`` names of a collection's scenes; plain ids of
        one scene), the share ``validation_tracks``, at least one and all but one, drawn from
        the seed, so that both sides drive every scene; in their order. A scene of one track
        keeps it in evolution."""
        if not self.validation_tracks:
            return ()
        scenes: dict[str, list[int]] = {}
        for i, name in enumerate(self.ego_tracks):
            scenes.setdefault(name.rpartition("/")[0], []).append(i)
        rng = stream(self.seed, Salt.VALIDATION_TRACKS)
        held = []
        for _, rows in sorted(scenes.items()):
            n = len(rows)
            if n >= 2:
                k = min(max(round(self.validation_tracks * n), 1), n - 1)
                held.extend(rows[j] for j in rng.permutation(n)[:k])
        return tuple(self.ego_tracks[i] for i in sorted(held))

    @property
    def overrides(self) -> dict:
        """The scenario overrides of the generations' episodes (the training tracks but
        :attr:`held_tracks` as the ego)."""
        held = set(self.held_tracks)
        return self._overrides(tuple(t for t in self.ego_tracks if t not in held))

    @property
    def validation_overrides(self) -> dict | None:
        """Those of the validation episodes when they drive :attr:`held_tracks`, else None
        (as :attr:`overrides`)."""
        held = self.held_tracks
        return self._overrides(held) if held else None

    def _overrides(self, tracks: tuple[str, ...]) -> dict:
        ego = {"ego": {"track": list(tracks)}} if tracks else {}
        return {"simulation": {"duration": self.episode_seconds}, **ego,
                **goal_overrides(self.goal_seconds)}  # fmt: skip


#: A run folder's README.md: what its files are and what to do with them.
RUN_README = """# A NeuroTrajectory training run

Made by `{command}` on {date}.

- `config.json`: every setting of the run (`"train"`), what train does after the
  generations (`"after"`) and the settings' digest (`"run"`)
- `inputs.json`: the SHA-256 of the scenario's files and of the code when the run began (a
  resume on other data is refused; with other code, warned about)
- `checkpoint.npz`: the last complete generation, its genomes and fitness
- `history.json`: every generation's fitness, Pareto ranks, hypervolume, timing, and the
  knee's validation score (the learning curve)
- `warm_start.npz`: the warm start's genome (runs with a warm start)
- `warm_start_fit.pt`: the warm start's fit as far as it got, while it runs (saved after
  each epoch, every minute within one and at Ctrl-C; an interrupted fit goes on from it
  with `--resume`)
- `best_knee.npz`: the best validated knee of any generation (runs with a warm start)
- `front.npz`, `front.json`: the final Pareto front, weights and scores on the episodes it
  was chosen on
- `heldout.json`: the knee (its warm start, the destination curve) on held-out episodes
- `plots/`: objectives, front, hypervolume and learning curve (drawn again from the saved
  scores by `neurotrajectory plots --run {out}`)
- `.lock`: held while a process writes the run

Continue (or extend) it: `neurotrajectory train --resume {out}`.
Drive its knee into a video: `neurotrajectory rollout --run {out} --video knee.mp4`.
Compare it: `neurotrajectory evaluate --run {out} --out eval/NAME`.
"""

#: What ``train`` does after the generations, by default (``config.json`` ``"after"``).
AFTER_DEFAULTS = {"heldout": 20, "video": None}
#: How ``config.json`` names a ``--video`` inside the run folder: relative to it, wherever
#: the folder is moved or copied.
IN_RUN = "{run}/"


class Run:
    """A training run in ``out``."""

    def __init__(self, out: str | Path, config: TrainConfig, after: dict | None = None) -> None:
        self.out = Path(out)
        self.config = config
        self.net_config = config.net
        #: What ``train`` does after the generations: held-out episodes, a video.
        self.after = {**AFTER_DEFAULTS, **(after or {})}
        self._windows = None  # the pre-training windows, once loaded
        self._progress = False  # say what it does between the progress bars (train)
        #: The checkpoint's copy of a missing or damaged history.json, once read in its place
        self._history_repaired: dict | None = None
        #: Settings a resume changed, written to config.json once it trains (a resume refused
        #: before, by its inputs or its backend, leaves the run as it was)
        self._unsaved = False

    # -- run directory ------------------------------------------------------------------------
    @classmethod
    def create(cls, out: str | Path, config: TrainConfig, command: str | None = None,
               **after) -> Run:  # fmt: skip
        """A new run in ``out``. Everything is checked (the folder, the scenario with the
        network, the pre-training data) before anything is written, so that a failure leaves
        ``out`` as it was. ``after``: what ``train`` does after the generations
        (:data:`AFTER_DEFAULTS`; None: the default); ``command``: the command line that
        made it, for the folder's ``README.md``. A process that writes the run holds its
        folder: :func:`run_folder`."""
        out = Path(out)
        problem = new_folder_problem(out, hint=f"use --resume {out} or another --out")
        if problem:
            raise RunError(f"--out {out}: {problem}")
        config, windows = _checked(config)
        run = cls(out, config, {k: v for k, v in after.items() if v is not None})
        out.mkdir(parents=True, exist_ok=True)
        run._windows = windows
        run._write_config()
        from gridsim.scenario.collection import input_digest

        run._write_inputs(input_digest(config.scenario))
        write_text(out / "README.md", RUN_README.format(
            command=command or "the Python API (neurotrajectory.evolve.runs.Run)",
            date=time.strftime("%Y-%m-%d %H:%M"), out=out))  # fmt: skip
        return run

    def note_resumed(self, command: str) -> None:
        """Add ``command`` (the command line that resumes the run) and the date to the run's
        ``README.md``, under how it was made and resumed before (a run without a README,
        made before runs had one, is left without)."""
        path = self.out / "README.md"
        try:
            lines = path.read_text().splitlines(keepends=True)
        except OSError:
            return
        said = [i for i, line in enumerate(lines) if line.startswith(("Made by", "Resumed by"))]
        if not said:
            return
        line = f"Resumed by `{command}` on {time.strftime('%Y-%m-%d %H:%M')}.\n"
        lines[said[-1] + 1 : said[-1] + 1] = ["\n", line]
        write_text(path, "".join(lines))

    def _write_config(self) -> None:
        after = dict(self.after)
        video, here = after.get("video"), self.out.resolve()
        if video and Path(video).resolve().is_relative_to(here):
            # a video inside the run stays with it when the run is moved or copied
            after["video"] = IN_RUN + Path(video).resolve().relative_to(here).as_posix()
        doc = {"format": FORMAT_VERSION, "run": self.fingerprint, "train": self.config.as_dict(),
               "after": after}  # fmt: skip
        write_json(self.out / "config.json", doc)

    @property
    def fingerprint(self) -> str:
        """The run's identity: a digest of every setting that shapes its results (not those a
        resume may change, :attr:`TrainConfig.RESUMABLE`). Its checkpoint carries it."""
        unstamped = TrainConfig.UNSTAMPED_DEFAULTS
        doc = {k: v for k, v in self.config.as_dict().items() if k not in TrainConfig.RESUMABLE
               and not (k in unstamped and v == unstamped[k])}  # fmt: skip
        return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()[:16]

    @classmethod
    def open(cls, out: str | Path, heldout=None, video=None, **changes) -> Run:
        """Reopen a run directory; ``changes`` may only touch :attr:`TrainConfig.RESUMABLE`;
        ``heldout`` and ``video`` (what ``train`` does after the generations) replace the
        run's if given."""
        out = Path(out)
        after = {"heldout": heldout, "video": video}
        cfg_path = out / "config.json"
        doc = read_manifest(out, "config.json", "run directory", RunError, (1, FORMAT_VERSION),
                            keys=("train",))  # fmt: skip
        if not isinstance(doc["train"], dict):
            raise RunError(f"{cfg_path}: 'train' must be an object, got {doc['train']!r}")
        try:
            known = set(TrainConfig.model_fields)
            legacy = TrainConfig.LEGACY if doc["format"] == 1 else TrainConfig.LATER
            stored = TrainConfig(
                **{**legacy, **{k: v for k, v in doc["train"].items() if k in known}}
            )
        except (KeyError, TypeError) as exc:
            raise RunError(f"{cfg_path}: unreadable run configuration ({exc})") from None
        except RunError as exc:
            raise RunError(f"{cfg_path}: {exc}") from None
        clash = {
            k: (getattr(stored, k), v)
            for k, v in changes.items()
            if v is not None and k not in TrainConfig.RESUMABLE and getattr(stored, k) != v
        }
        if clash:
            raise SettingsClash(out, clash)
        allowed = {k: v for k, v in changes.items() if v is not None and k in TrainConfig.RESUMABLE}
        config = stored.replace(**allowed)
        kept = doc.get("after") if isinstance(doc.get("after"), dict) else {}
        if isinstance(kept.get("video"), str) and kept["video"].startswith(IN_RUN):
            kept = {**kept, "video": str(out / kept["video"].removeprefix(IN_RUN))}
        given = {k: v for k, v in after.items() if v is not None}
        run = cls(out, config, {k: kept[k] for k in AFTER_DEFAULTS if k in kept} | given)
        done = run.completed_generations() if "generations" in allowed else 0
        if config.generations < done:
            raise RunError(f"{out}: --generations {config.generations} is fewer than the "
                           f"{done} generations the run has done; give >= {done} (or "
                           "leave it out to finish the run as configured)")  # fmt: skip
        _check_workers(config)
        run._unsaved = bool(allowed or given)
        return run

    def _write_inputs(self, files: dict[str, str]) -> None:
        """:data:`INPUTS_FILE`: the scenario's files (``files``, their digests) and the code
        (:func:`code_digest`)."""
        write_json(self.out / INPUTS_FILE, {"scenario": self.config.scenario, "files": files,
                                            "code": code_digest()})  # fmt: skip

    def check_inputs(self) -> None:
        """A :class:`RunError` when the files the run's scenario is read from changed since
        it began (:data:`INPUTS_FILE`): its next generations would train on other data. A
        warning when the code did (:func:`code_digest`; not kept by runs begun before it
        was), or when :data:`INPUTS_FILE` is missing from a run that has generations (then
        nothing can be checked: it is written again, of the files and code of now)."""
        from gridsim.scenario.collection import input_changes, input_digest

        def files_now() -> dict[str, str]:
            try:
                return input_digest(self.config.scenario)
            except GridSimError as exc:
                raise RunError(flagged("--scenario", self.config.scenario, exc)) from None

        path = self.out / INPUTS_FILE
        if not path.exists():
            if self.completed_generations():
                warn_data(f"{path} is missing: whether the run's scenario files and code are "
                          "those it began with cannot be checked (if they changed, its next "
                          "generations train on other data or by other code); it is written "
                          "again, of them as they are now")  # fmt: skip
                self._write_inputs(files_now())
            return
        doc = self._inputs()
        began, code = doc.get("code"), code_digest()
        if isinstance(began, dict) and began != code:
            warn_data(f"{self.out} began with other code (gridsim {began.get('version')}, "
                      f"sources {began.get('sources')}; now {code['version']}, "
                      f"{code['sources']}): its next generations are trained by the code of "
                      "now, so its result is that of neither code's run from the start (resume "
                      "it with the code it began with to get that)")  # fmt: skip
        what = input_changes(doc["files"], files_now())
        if what:
            raise RunError(f"{self.out}: the files of --scenario {self.config.scenario} are not "
                           f"those the run began with ({what}): its next generations would "
                           "train on other data. Restore them, or start a new run with "
                           "another --out")  # fmt: skip

    def _inputs(self) -> dict:
        """:data:`INPUTS_FILE`, read and checked."""
        path = self.out / INPUTS_FILE
        try:
            doc = json.loads(path.read_text())
            kept = doc["files"]
            if not isinstance(kept, dict):
                raise TypeError(f"'files' is a {type(kept).__name__}, not a mapping")
        except (OSError, ValueError, KeyError, TypeError) as exc:
            raise RunError(f"{path}: unreadable ({type(exc).__name__}: {exc})") from None
        return doc

    def warn_changed_inputs(self) -> None:
        """A warning when the files the run's scenario is read from changed since it began:
        its members are then driven (held-out episodes, videos, evaluations) on other data
        than they trained on; said too when :data:`INPUTS_FILE` cannot be read or is missing
        (deleted, or a run begun with gridsim 0.2.0 or earlier). Nothing for a scenario that
        does not load (driving it says why)."""
        from gridsim.scenario.collection import input_changes, input_digest

        path = self.out / INPUTS_FILE
        if not path.exists():
            warn_data(f"{path} is missing (deleted, or the run began with gridsim 0.2.0 or "
                      "earlier): whether the run's scenario files are those it trained on "
                      "cannot be checked")  # fmt: skip
            return
        try:
            kept = self._inputs()["files"]
        except RunError as exc:
            warn_data(f"{exc}: whether the run's scenario files are those it trained on "
                      "cannot be checked")  # fmt: skip
            return
        try:
            what = input_changes(kept, input_digest(self.config.scenario))
        except GridSimError:  # (a scenario that does not load: driving it says why)
            return
        if what:
            warn_data(f"{self.out}: the files of its scenario {self.config.scenario} are not "
                      f"those it trained on ({what}): its members are driven on the data of "
                      "now, and their figures are not the run's")  # fmt: skip

    def completed_generations(self) -> int:
        """How many generations the checkpoint holds (0 without one)."""
        path = self.out / "checkpoint.npz"
        if not path.exists():
            return 0
        try:
            with np.load(path) as data:
                return int(data["generation"]) + 1
        except Exception as exc:
            raise RunError(f"{path}: corrupt checkpoint ({exc})") from None

    def load_checkpoint(self):
        """``(generation, population, fitness, violation)`` of the last complete generation, or
        None. A checkpoint of another run (another :attr:`fingerprint`) is refused."""
        path = self.out / "checkpoint.npz"
        if not path.exists():
            return None
        try:
            with np.load(path) as data:
                gen, pop, fit = int(data["generation"]), data["population"], data["fitness"]
                violation = data["violation"] if "violation" in data else np.zeros(len(fit))
                owner = str(data["run"]) if "run" in data else None
        except Exception as exc:
            raise RunError(f"{path}: corrupt checkpoint ({exc})") from None
        if owner is not None and owner != self.fingerprint:
            raise RunError(f"{path}: the checkpoint of another run (run {owner}; this run, by "
                           f"its config.json, is {self.fingerprint}): restore this run's "
                           "checkpoint, or start a new run with another --out")  # fmt: skip
        if pop.shape[0] != self.config.population or fit.shape != (self.config.population, 3):
            raise RunError(f"{path}: population {pop.shape[0]} does not match the configuration "
                           f"({self.config.population})")  # fmt: skip
        return gen, pop, fit, violation

    def _checkpoint_history(self) -> dict | None:
        """The copy of ``history.json`` the checkpoint holds, or None (no checkpoint, or
        one from before it held it)."""
        path = self.out / "checkpoint.npz"
        if not path.exists():
            return None
        try:
            with np.load(path) as data:
                doc = json.loads(str(data["history"])) if "history" in data else None
        except Exception as exc:
            raise RunError(f"{path}: corrupt checkpoint ({exc})") from None
        return doc if isinstance(doc, dict) and "generations" in doc else None

    def _history_of_checkpoint(self, found: int, kept: int) -> list[dict]:
        """The history the checkpoint of ``kept`` generations holds, written again as
        ``history.json`` (which has ``found``: the run stopped between the two writes); a
        :class:`RunError` when it holds none (a checkpoint from before it did) or another
        count."""
        doc = self._checkpoint_history()
        if doc is None or len(doc.get("generations", ())) != kept:
            raise RunError(f"{self.out}: history.json has {found} generations, checkpoint.npz "
                           f"{kept}: they disagree; restore both or start a new run with "
                           "another --out")  # fmt: skip
        write_json(self.out / "history.json", doc)
        self.say(f"{self.out}: history.json had {found} generations and the checkpoint "
                  f"{kept}: the run stopped between their writes; the checkpoint's history is "
                  "kept")  # fmt: skip
        return doc["generations"]

    def _violation(self, violation: np.ndarray, fitness: np.ndarray) -> np.ndarray | None:
        """What selection sees of the constraint: the share of episode time lost (nothing for
        unconstrained runs); anchored, with l1 worse than the anchor's below that
        (:func:`~neurotrajectory.evolve.evolution.anchored_violation`)."""
        if self.config.anchored:
            lost = violation if self.config.constrained else np.zeros(len(fitness))
            return anchored_violation(fitness, lost)
        return violation if self.config.constrained else None

    def _hypervolumes(self) -> list[float]:
        """Each generation's :func:`~neurotrajectory.evolve.pareto.generation_hypervolume`
        (the hypervolume plot's and the progress bar's figure)."""
        history = self.load_history()
        return [generation_hypervolume(h, history[0], self.config.anchored) for h in history]

    def load_history(self) -> list[dict]:
        """The generations' records (``history.json``); where it is missing or cannot be
        read, the copy the checkpoint holds, said (nothing without either)."""
        path = self.out / "history.json"
        try:
            doc = json.loads(path.read_text())
            generations = doc["generations"]
        except (FileNotFoundError, ValueError, KeyError, TypeError) as exc:
            kept = self._checkpoint_history()
            if kept is None:
                if isinstance(exc, FileNotFoundError):
                    return []
                raise RunError(f"{path}: corrupt history ({type(exc).__name__}: {exc}); the "
                               "checkpoint holds no copy: restore it, or start a new run "
                               "with another --out") from None  # fmt: skip
            why = "is missing" if isinstance(exc, FileNotFoundError) else "cannot be read"
            warn_data(f"{path} {why}: the copy of the history the checkpoint holds is used "
                      f"({counted(len(kept['generations']), 'generation')})")  # fmt: skip
            doc, generations = kept, kept["generations"]
            self._history_repaired = kept  # (the training loop writes it back)
        if doc.get("run", self.fingerprint) != self.fingerprint:
            raise RunError(f"{path}: the history of another run (run {doc['run']}; this run is "
                           f"{self.fingerprint}): restore this run's history.json, or start a "
                           "new run with another --out")  # fmt: skip
        return generations

    # -- the loop ------------------------------------------------------------------------------
    def train(self, progress: bool = True, stop_after: int | None = None) -> dict:
        """Run (or continue) the generations. ``stop_after`` ends the process after that many
        new generations (for tests of interrupted runs)."""
        cfg = self.config
        self._progress = progress
        spec = WorkerSpec(cfg.scenario, cfg.overrides, self.net_config, cfg.episode_seeds(0),
                          batch=cfg.batch, evolve=cfg.evolve,
                          validation_overrides=cfg.validation_overrides)  # fmt: skip
        backend = make_backend(cfg.backend, spec, cfg.workers, cfg.ray_address)
        try:
            if self._unsaved:  # (the resume's settings: the backend started with them)
                self._write_config()
                self._unsaved = False
            return self._loop(backend, progress, stop_after)
        finally:
            backend.close()

    def _loop(self, backend, progress, stop_after) -> dict:
        cfg = self.config
        probe = TrajectoryNet(scenario_net_config(cfg.scenario, cfg.overrides, self.net_config))
        history = self.load_history()
        if self._history_repaired is not None:  # written back: later readers need no copy
            write_json(self.out / "history.json", self._history_repaired)
        ckpt = self.load_checkpoint()
        if ckpt is None and history:
            raise RunError(f"{self.out}: history.json has {len(history)} generations but "
                           "checkpoint.npz is missing: restore it, or start a new run "
                           "with another --out")  # fmt: skip
        problem = genome_mismatch(probe, ckpt[1].shape[1]) if ckpt is not None else None
        if problem:
            raise RunError(f"{self.out / 'checkpoint.npz'}: {problem}")
        if ckpt is not None and len(history) != ckpt[0] + 1:
            history = self._history_of_checkpoint(len(history), ckpt[0] + 1)
        if ckpt is not None:
            source = Source.CHECKPOINT
        elif cfg.warm_started:
            source = Source.WARM_START
        else:
            source = Source.RANDOM
        population = backend.population  # the workers' generation, as checkpoints save it
        first = self._start(source, probe, population, ckpt)
        if first.parents is not None:
            backend.load(first.parents)
        backend.advance(first.recipes)
        bar = progress_bar(range(first.generation, cfg.generations), desc="generations",
                           unit="gen", disable=not progress, initial=first.generation,
                           total=cfg.generations)  # fmt: skip
        for done, gen in enumerate(bar, start=1):
            t0 = time.perf_counter()
            fitness, stats = backend.evaluate(cfg.population, cfg.episode_seeds(gen))
            violation = np.array([s.get("lost", 0.0) for s in stats])
            recipes, rank, parents = self._next_generation(population.genomes, gen, fitness,
                                                           violation)  # fmt: skip
            record = self._record(gen, fitness, violation, rank, stats,
                                  time.perf_counter() - t0, history)  # fmt: skip
            record |= self._validate_knee(backend, gen, fitness, rank, source)
            if cfg.anchored and "knee_validation" in record:
                self._keep_best_knee(population, gen, record["knee_validation"], history)
            history.append(record)
            doc = {"run": self.fingerprint, "generations": history}
            write_npz(
                self.out / "checkpoint.npz",
                generation=np.array(gen),
                population=population.genomes,
                fitness=fitness,
                violation=violation,
                run=np.array(self.fingerprint),
                # the history too: the two files are written one after the other, and a run
                # stopped between them resumes from the checkpoint's
                history=np.array(json.dumps(doc)),
            )
            write_json(self.out / "history.json", doc)
            # the hypervolume plot's figure: what the generation dominates beyond its reference
            hv = generation_hypervolume(history[-1], history[0], cfg.anchored)
            bar.set_postfix(hv=f"{hv:.2f}", front=int(np.sum(rank == 0)))
            if gen + 1 < cfg.generations:
                if parents is not None:
                    backend.load(parents)
                backend.advance(recipes)
            if stop_after is not None and done >= stop_after:
                return {"stopped_at": gen}
        return self.finish(backend)

    def _start(self, source: Source, probe: TrajectoryNet, population: Population, ckpt) -> Start:
        """The first generation this call evaluates, made from ``source``: generation 0 from
        random weights; generation 0 around the warm start's genome (see :meth:`_warm_start`):
        itself as individual 0 and ``sigma``-mutations of it; or, resuming, the generation
        after the checkpoint's ``ckpt``."""
        cfg = self.config
        if source is Source.CHECKPOINT:
            gen, genomes, fitness, violation = ckpt
            recipes, _, parents = self._next_generation(genomes, gen, fitness, violation)
            return Start(gen + 1, recipes, genomes if parents is None else parents)
        if source is Source.WARM_START:
            base = self._saved_warm_start(probe)
            if base is None:
                base = self._warm_start(probe)
            table = len(population.table)
            if cfg.es:
                rng = stream(cfg.seed, Salt.WARM_START_MUTATIONS)
                recipes = es_recipes(cfg.ga, rng, len(base), table)
            else:
                recipes = warm_start_recipes(cfg.ga, cfg.seed, len(base), table)
            return Start(0, recipes, base[None])
        return Start(0, initial_recipes(cfg.ga, cfg.seed))

    def _next_generation(self, genomes: np.ndarray, gen, fitness, violation):
        """``(recipes, rank, parents)``: the recipes of the generation after ``gen`` (of
        ``genomes``), its (constrained) Pareto ranks, and the parents the recipes apply to
        (None: ``genomes`` themselves; evolution strategies: the next centre)."""
        cfg = self.config
        size = genomes.shape[1]
        table = table_size(size)
        if cfg.es:
            rank = non_dominated_sort(minimised(fitness), self._violation(violation, fitness))
            centre = es_centre(genomes, fitness, violation, cfg.es_step)
            recipes = es_recipes(cfg.ga, generation_rng(cfg.seed, gen), size, table)
            return recipes, rank, centre[None]
        recipes, rank = next_generation(fitness, cfg.ga, cfg.seed, gen, size, table,
                                        self._violation(violation, fitness),
                                        anchored=cfg.anchored)  # fmt: skip
        return recipes, rank, None

    def _keep_best_knee(self, population: Population, gen: int, score: dict, history) -> None:
        """Keep generation ``gen``'s knee (``score``: on the validation episodes) in
        :data:`BEST_KNEE_FILE` if it is better than every earlier generation's: it lost less
        episode time, or as little and its l1 is lower (the first of equals is kept)."""

        def key(v: dict) -> tuple[float, float]:
            return (v["violation"], v["l1"])

        earlier = [key(h["knee_validation"]) for h in history if "knee_validation" in h]
        if earlier and not key(score) < min(earlier):
            return
        write_npz(self.out / BEST_KNEE_FILE, genome=population.genomes[score["index"]],
                  generation=np.array(gen))  # fmt: skip

    def _best_knee(self) -> tuple[int, np.ndarray] | None:
        """``(generation, genome)`` of :data:`BEST_KNEE_FILE`, or None."""
        data = _read_npz(self.out / BEST_KNEE_FILE, "generation", "genome")
        return None if data is None else (int(data[0]), data[1])

    def _validate_knee(self, backend, gen, fitness, rank, source: Source) -> dict:
        """The learning curve's point of generation ``gen``: its knee (picked from its first
        front on its own episodes) evaluated on the validation episodes; in generation 0 of a
        warm-started run also the warm start (individual 0). Nothing without validation
        episodes."""
        seeds = self.config.validation_seeds
        if not seeds:
            return {}
        front = np.flatnonzero(rank == 0)
        knee = ANCHOR if self.config.es else int(front[pick_member(fitness[front], "knee")])
        warm = gen == 0 and source is Source.WARM_START
        members = [knee] + ([ANCHOR] if warm and knee != ANCHOR else [])
        fit, stats = backend.evaluate_members(members, seeds, validation=True)
        scores = {i: _score(i, f, s) for i, f, s in zip(members, fit, stats, strict=True)}
        out = {"knee_validation": scores[knee]}
        if warm:
            out["warm_start_validation"] = scores[ANCHOR]
        return out

    def _warm_start(self, probe: TrajectoryNet) -> np.ndarray:
        """The warm start's genome; writes ``pretrain.json`` and :data:`WARM_START_FILE`.
        Fits the network to the pre-training windows; each DAgger round then drives the
        fitted network on the pre-training episodes, labels every state it visits with the
        human's next set-points from there, and fits a fresh start to all windows so far (same
        seed, same held-out tracks, validated on human windows only; ``dagger_weight`` weighs
        the visited windows), so that the network learns to recover from its own mistakes."""
        from neurotrajectory.evolve.warm_start import pretrain_genome

        cfg = self.config
        if cfg.pretrain:
            self.say(f"warm start: reading the windows of {cfg.pretrain}")
        else:
            self.say(f"warm start: recording {cfg.pretrain_episodes} episodes of "
                     f"{PRETRAIN_EPISODE_SECONDS:g} s on {cfg.scenario}")  # fmt: skip
        windows, source, episodes = self._pretrain_windows()
        start = initial_genome(probe, initial_recipes(cfg.ga, cfg.seed)[0].init_seed)
        held = "" if cfg.pretrain_validation <= 0 else (  # (split by track in the fit)
            f", less the windows of {cfg.pretrain_validation:.0%} of their tracks, held out to "
            "validate the fit")  # fmt: skip
        self.say(f"warm start: fitting the network to {counted(len(windows), 'window')}{held} "
                 f"({counted(cfg.pretrain_epochs, 'epoch')} at most)")  # fmt: skip

        # a fit interrupted goes on from where it was saved; with DAgger rounds (several fits,
        # driving between them), a run interrupted in its warm start fits again from the start
        saved = None if cfg.dagger_rounds else self.out / WARM_START_FIT_FILE

        def fit(visited):
            return pretrain_genome(probe, start, windows, cfg.pretrain_epochs, cfg.seed,
                                   validation=cfg.pretrain_validation, visited=visited,
                                   visited_share=cfg.dagger_weight,
                                   progress=self._progress, checkpoint=saved)  # fmt: skip

        base, stats = fit(None)
        visited, rounds = [], []
        stride = RECORDED_STRIDE if is_recorded(cfg.scenario) else GENERATED_STRIDE
        for _ in range(cfg.dagger_rounds):
            set_genome(probe, base.copy())
            driven = drive_windows(cfg.scenario, episodes, stride, NetPolicy(probe),
                                   labels=cfg.dagger_labels)  # fmt: skip
            visited += [] if driven is None else [driven]
            base, stats = fit(Windows.concat(visited) if visited else None)
            rounds.append({"visited_windows": 0 if driven is None else len(driven),
                           **{k: stats[k] for k in ("windows", "validation_windows",
                                                    "best_epoch", "validation_mse")
                              if k in stats}})  # fmt: skip
        if rounds:
            stats |= {"dagger": rounds, "dagger_weight": cfg.dagger_weight}
        if "validation_mse" in stats:
            best = stats["best_epoch"]
            epochs = len(stats["validation_mse"]) - 1
            start = (
                "the ridge fit of the read-outs alone"
                if "ridge_penalty" in stats
                else "the network it started from"
            )  # (--no-skip: no ridge fit)
            kept = (f"epoch {best} of {epochs} kept" if best else f"{start} kept: none of the "
                    f"{epochs} epochs of gradient descent predicted the held-out tracks "
                    "better")  # fmt: skip
            self.say(f"warm start: validation MSE {stats['validation_mse'][best]:.4g} m^2 on "
                     f"{stats['validation_windows']} windows of held-out tracks ({kept}; "
                     "pretrain.json)")  # fmt: skip
        write_json(self.out / "pretrain.json", {**source, **stats})
        write_npz(self.out / WARM_START_FILE, genome=base,
                  net=np.array(json.dumps(self.net_config.to_dict())))  # fmt: skip
        return base

    def say(self, message: str) -> None:
        """Print what the run does now to stderr, between its progress bars (not --quiet)."""
        if self._progress:
            tqdm.write(f"neurotrajectory: {message}", file=sys.stderr)

    def _saved_warm_start(self, probe: TrajectoryNet) -> np.ndarray | None:
        """The warm start an interrupted first attempt saved (fitting it again gives the same
        genome: it is deterministic), or None."""
        base = self.warm_start_genome()
        if base is not None and (problem := genome_mismatch(probe, len(base))):
            raise RunError(f"{self.out / WARM_START_FILE}: {problem}")
        return base

    def warm_start_genome(self) -> np.ndarray | None:
        """The warm start's genome (generation 0's parent), or None for a run without one
        (or saved before warm starts were kept)."""
        data = _read_npz(self.out / WARM_START_FILE, "genome")
        return None if data is None else data[0]

    def _pretrain_windows(self):
        """The warm start's windows, where they came from, and the episodes of the training
        scenario they were recorded on (to drive again): the dataset ``pretrain``, or
        ``pretrain_episodes`` episodes of the training scenario recorded now (training seeds,
        :data:`PRETRAIN_EPISODE_SECONDS` each)."""

        cfg = self.config
        if cfg.pretrain:
            if self._windows is None:
                self._windows = _pretrain_data(cfg.pretrain)
            return self._windows, {"data": str(cfg.pretrain)}, _dagger_episodes(cfg, self._windows)
        _check_pretrain_episodes(cfg)
        seeds = list(cfg.pretrain_seeds)
        episodes, _ = scenario_episodes(cfg.scenario, seeds=seeds,
                                        duration=PRETRAIN_EPISODE_SECONDS,
                                        goal_seconds=cfg.goal_seconds)  # fmt: skip
        windows = drive_windows(cfg.scenario, episodes, GENERATED_STRIDE)
        if windows is None:
            raise RunError(f"--pretrain-episodes: no windows were recorded on {cfg.scenario!r}")
        source = {"recorded_episodes": seeds, "episode_seconds": PRETRAIN_EPISODE_SECONDS}
        return windows, source, episodes

    def _record(self, gen, fitness, violation, rank, stats, seconds, history) -> dict:
        f = minimised(fitness)
        if history:  # normalise with the bounds of generation 0, fixed for the whole run
            lo, hi = np.array(history[0]["norm_lo"]), np.array(history[0]["norm_hi"])
        else:
            lo, hi = f.min(axis=0), f.max(axis=0)
        # an objective generation 0 did not spread (all members alike) is scaled by its size
        span = np.where(hi - lo > 0, hi - lo, np.maximum(np.abs(lo), 1e-9))
        front = (f[rank == 0] - lo) / span
        steps = sum(s.get("steps", 0) for s in stats)
        return {
            "generation": gen,
            "fitness": fitness.tolist(),
            "violation": violation.tolist(),
            "rank": rank.tolist(),
            "hypervolume": hypervolume(front, np.full(3, 1.1)),
            "norm_lo": lo.tolist(),
            "norm_hi": hi.tolist(),
            "seconds": seconds,
            "individual_steps": steps,
            "individual_steps_per_s": steps / seconds if seconds > 0 else 0.0,
            "collisions": sum(s.get("collisions", 0) for s in stats),
            "off_road": sum(s.get("off_road", 0) for s in stats),
            "reached": sum(s.get("reached", 0) for s in stats),
        }

    def finish(self, backend) -> dict:
        """Write the final front and the plots from the checkpoint and history. With
        ``validation_episodes``, the final population is evaluated again on them (more
        episodes than a generation's, none trained on) and the front is chosen on that;
        anchored, with the best validated knee of any generation as one more candidate
        (index ``population``), unless the last population holds it."""
        from neurotrajectory.evolve.plots import plot_run

        ckpt = self.load_checkpoint()
        if ckpt is None:
            raise RunError(f"{self.out}: no complete generation yet")
        gen, population, fitness, violation = ckpt
        seeds = self.config.validation_seeds
        best = self._best_knee() if self.config.anchored and seeds else None
        if best is not None and not any(np.array_equal(best[1], g) for g in population):
            population = np.vstack([population, best[1][None]])  # a candidate too
        else:
            best = None
        if seeds:
            self.say(f"choosing the final front: {len(population)} members on {len(seeds)} "
                     "validation episodes")  # fmt: skip
            backend.load(population)
            fitness, stats = backend.evaluate(len(population), seeds, validation=True)
            violation = np.array([s.get("lost", 0.0) for s in stats])
        rank = non_dominated_sort(minimised(fitness), self._violation(violation, fitness))
        members = _distinct(population, np.flatnonzero(rank == 0))
        write_npz(
            self.out / "front.npz",
            genomes=population[members],
            fitness=fitness[members],
            violation=violation[members],
            indices=members,
            net=np.array(json.dumps(self.net_config.to_dict())),
        )
        summary = {
            "generation": gen,
            "chosen_on": f"{len(seeds)} validation episodes" if seeds else "the last generation",
            # "member": its place in the front (as train prints it, rollout --pick and
            # heldout.json name it); "index": its place among the candidates
            "front": [
                {
                    "member": k,
                    "index": int(i),
                    "l1": float(fitness[i, 0]),
                    "l2": float(fitness[i, 1]),
                    "l3": float(fitness[i, 2]),
                    "violation": float(violation[i]),
                }
                for k, i in enumerate(members)
            ],  # fmt: skip
            # per generation, the hypervolume plot's and the progress bar's figure
            "hypervolume": self._hypervolumes(),
            # every member the front was chosen from, so that the plots can be drawn again
            "candidates": [
                {
                    "l1": float(f[0]),
                    "l2": float(f[1]),
                    "l3": float(f[2]),
                    "rank": int(r),
                    "violation": float(v),
                }
                for f, r, v in zip(fitness, rank, violation, strict=True)
            ],  # fmt: skip
        }
        history = self.load_history()
        if seeds and history and "warm_start_validation" in history[0]:
            # on the same episodes; "index": the candidate that is the warm start (anchored:
            # individual 0), none where none is (evolution strategies: the centre moved on)
            warm = {k: v for k, v in history[0]["warm_start_validation"].items() if k != "index"}
            genome = self.warm_start_genome()
            held = [i for i, g in enumerate(population)
                    if genome is not None and np.array_equal(g, genome)]  # fmt: skip
            summary["warm_start"] = ({"index": held[0]} if held else {}) | warm
        if best is not None:  # the last candidate: the best validated knee of any generation
            summary["best_knee"] = {"generation": best[0], "index": len(population) - 1}
        write_json(self.out / "front.json", summary)
        plot_run(self.out, history, (fitness, rank, violation), summary["chosen_on"],
                 anchored=self.config.anchored, centre=self.config.es,
                 warm_start=summary.get("warm_start"))  # fmt: skip
        return summary

    def plot(self) -> list[Path]:
        """Draw the run's plots again from ``history.json`` and ``front.json`` (as this
        version draws them); nothing is evaluated. A front written before ``front.json`` kept
        every candidate is drawn from its members alone; one older than the last generation
        (a resumed run stopped before its end) is left out: the front plot then shows the
        last generation on its training episodes."""
        from neurotrajectory.evolve.plots import plot_run

        history = self.load_history()
        if not history:
            raise RunError(f"{self.out}: no generation yet, nothing to plot")
        path = self.out / "front.json"
        final, chosen_on, warm = None, "", None
        if path.exists():
            try:
                summary = json.loads(path.read_text())
                rows = summary.get("candidates") or summary["front"]
                fitness = np.array([[r["l1"], r["l2"], r["l3"]] for r in rows], dtype=float)
                rank = np.array([r.get("rank", 0) for r in rows])
                violation = np.array([r["violation"] for r in rows], dtype=float)
            except (OSError, ValueError, KeyError, TypeError) as exc:
                raise RunError(f"{path}: unreadable front ({type(exc).__name__}: {exc})") from None
            chosen_on = summary.get("chosen_on", "")
            if "candidates" not in summary:
                chosen_on += " (its members only: the front predates the saved candidates)"
            if summary.get("generation") == history[-1]["generation"]:
                final, warm = (fitness, rank, violation), summary.get("warm_start")
        return plot_run(self.out, history, final, chosen_on, anchored=self.config.anchored,
                        centre=self.config.es, warm_start=warm)  # fmt: skip


def _distinct(genomes: np.ndarray, members: np.ndarray) -> np.ndarray:
    """``members`` (indices into ``genomes``) without the repeats of a genome listed before
    (an elite carried over twice is one network: the front lists it once)."""
    kept: list[int] = []
    for i in members:
        if not any(np.array_equal(genomes[i], genomes[k]) for k in kept):
            kept.append(int(i))
    return np.array(kept, dtype=members.dtype)


@contextmanager
def run_folder(out: str | Path, resume: bool, flag: str | None = None) -> Iterator[Path]:
    """Hold the run folder ``out`` while the block writes it: one process at a time
    (:func:`~gridsim.outputs.folder_lock`; a second one is refused, naming the first). For a
    new run (not ``resume``), ``out`` must be new or empty, and if the block fails before a
    generation is complete, what it wrote is removed again (the folder too, if it made it),
    so that the corrected command can run in the same ``--out``; later the run stays, to be
    resumed (from the first complete generation on, or from the warm start once it is saved,
    which can take minutes to fit). ``flag``: the command's flag that named ``out``, for its
    errors (default ``--resume`` or ``--out``)."""
    flag = flag or ("--resume" if resume else "--out")
    out = Path(out)
    if resume:  # a run folder, not one the lock would make
        read_manifest(out, "config.json", "run directory", RunError, (1, FORMAT_VERSION))
        if problem := output_problem(out, directory=True):
            raise RunError(f"{flag} {out}: {problem}: a run goes on in its own folder (copy "
                           "it somewhere writable and resume the copy)")  # fmt: skip
    else:
        problem = new_folder_problem(out, hint=f"use --resume {out} or another --out")
        if problem:
            raise RunError(f"{flag} {out}: {problem}")
    existed = out.exists()
    with folder_lock(out, flag):
        if resume:  # a write a killed process left half done (a checkpoint's can take GBs)
            for stale in out.glob(".*.tmp"):
                stale.unlink(missing_ok=True)
        try:
            yield out
        except BaseException:
            kept = [f for f in ("checkpoint.npz", WARM_START_FILE, WARM_START_FIT_FILE)
                    if (out / f).exists()]  # fmt: skip
            if not resume and not kept:
                _undo(out, remove_folder=not existed)
            raise


def _undo(out: Path, remove_folder: bool) -> None:
    """Remove what a new run wrote into ``out`` (which was empty or did not exist)."""
    if remove_folder:
        shutil.rmtree(out, ignore_errors=True)
    else:
        empty_folder(out)


def _checked(config: TrainConfig):
    """``(config, windows)``: the configuration checked against its scenario, network and
    pre-training data (the data's windows, or None), with :func:`_with_training_tracks`."""
    from gridsim.envs.gridsim_env import GridSimEnv
    from gridsim.scenario.collection import load_collection

    try:
        load_collection(config.scenario)
    except GridSimError as exc:
        raise RunError(flagged("--scenario", config.scenario, exc)) from None
    try:
        env = GridSimEnv(config.scenario, **config.overrides)
    except GridSimError as exc:
        goal = f" --goal-seconds {config.goal_seconds:g}" if config.goal_seconds else ""
        raise RunError(f"--episode-seconds {config.episode_seconds:g}{goal} on "
                       f"{config.scenario}: {exc}") from None  # fmt: skip
    try:
        env.reset(seed=0)  # builds a world: the map, the traffic and its library
    except GridSimError as exc:
        raise RunError(flagged("--scenario", config.scenario, exc)) from None
    probe = TrajectoryNet(net_config_for(env.cfg, config.net))
    _check_size(config, sum(p.numel() for p in probe.parameters()))
    windows = None
    if config.pretrain:
        windows = _pretrain_data(config.pretrain)
        manifest = dataset_manifest(config.pretrain)  # (the windows: read before)
        problem = (size_mismatch(probe.cfg, windows) or _goal_mismatch(manifest, env.cfg.env)
                   or recording_mismatch(manifest, env.cfg))  # fmt: skip
        if problem:
            raise RunError(f"--pretrain {config.pretrain}: {problem}")
        _dagger_episodes(config, windows)
    elif config.pretrain_episodes:
        _check_pretrain_episodes(config)
    config = _with_training_tracks(config, windows)
    if config.validation_tracks and not config.ego_tracks:
        raise RunError(f"--validation-tracks {config.validation_tracks:g} holds out some of "
                       "the training tracks of a recorded scene: train on a recorded scene "
                       "with --pretrain DATA (windows of at least 2 of its tracks)")  # fmt: skip
    if config.validation_overrides is not None:  # the validation episodes can be driven
        try:
            GridSimEnv(config.scenario, **config.validation_overrides).reset(seed=0)
        except GridSimError as exc:
            raise RunError(f"--validation-tracks {config.validation_tracks:g}: "
                           f"{exc}") from None  # fmt: skip
    return config, windows


#: The share of the machine's memory a run's populations may take (parents and children).
MEMORY_SHARE = 0.5


def _check_size(config: TrainConfig, weights: int) -> None:
    """A :class:`RunError`, before anything is allocated, when the populations would not fit
    in :data:`MEMORY_SHARE` of this machine's memory, or ``processes`` asks for far more
    workers than it has cores."""
    need = 2 * config.population * weights * 4  # float32 genomes of parents and children
    have = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    if need > MEMORY_SHARE * have:
        raise RunError(f"--population {config.population} of networks of {weights:,} weights "
                       f"needs {need / 1e9:.3g} GB for its genomes; this machine has "
                       f"{have / 1e9:.3g} GB: choose a smaller population or preset")  # fmt: skip
    _check_workers(config)


def _check_workers(config: TrainConfig) -> None:
    """A :class:`RunError` when ``processes`` asks for far more workers than this machine
    has cores (a new run's and a resume's: each worker holds an environment and a network)."""
    cores = os.cpu_count() or 1
    if config.backend == "processes" and config.workers > 4 * cores:
        raise RunError(f"--workers {config.workers}: this machine has {cores} cores; give at "
                       f"most {4 * cores} (one per core is best)")  # fmt: skip


def _goal_mismatch(manifest: dict, env) -> str | None:
    """Why the pre-training dataset of ``manifest`` was recorded with another destination than
    the run gives its network (``env``: the run's :class:`~gridsim.scenario.schema.EnvConfig`)."""
    data = manifest.get("goal_seconds")
    run = env.goal_seconds
    if data == run:
        return None

    def said(goal):
        return "at the last set-point" if goal is None else f"{goal:g} s ahead"

    flag = "leave out --goal-seconds" if data is None else f"--goal-seconds {data:g}"
    return (
        f"its windows see the destination {said(data)}, the run's network "
        f"{said(run)}: record them with the run's --goal-seconds, or {flag}"
    )


def _pretrain_data(folder: str):

    try:
        return load_dataset(folder).windows
    except DatasetError as exc:
        raise RunError(flagged("--pretrain", folder, exc)) from None


def _dagger_episodes(config: TrainConfig, windows) -> list:
    """The episodes of the training scenario the pre-training ``windows`` were recorded on
    (to drive again); a :class:`RunError` if DAgger rounds need them and there are none."""
    from gridsim.scenario.collection import is_collection

    if is_collection(config.scenario):
        if config.dagger_rounds:
            raise RunError(f"--dagger-rounds: not on a collection of scenarios "
                           f"({config.scenario!r}); train on one scenario")  # fmt: skip
        return []
    episodes = episodes_of(windows, config.scenario, PRETRAIN_EPISODE_SECONDS, config.goal_seconds)
    if config.dagger_rounds and not episodes:
        raise RunError(f"--dagger-rounds: --pretrain {config.pretrain} holds no episode of the "
                       f"training scenario {config.scenario!r} to drive again")  # fmt: skip
    return episodes


def _check_pretrain_episodes(config: TrainConfig) -> None:

    if has_recorded(config.scenario):  # (its tracks would all be driven: none held out)
        raise RunError(f"--pretrain-episodes: {config.scenario!r} replays a recorded scene; "
                       "record windows of its training tracks and pass them as "
                       "--pretrain DATA")  # fmt: skip


def _with_training_tracks(config: TrainConfig, windows) -> TrainConfig:
    """On a recorded scene (or a collection with recorded scenes, generated ones beside them
    or not) with pre-training data (``windows``) and no ``ego_tracks``: the data's tracks of
    that scene (of a collection: of each of its recorded scenes, as ``SCENE/ID`` names), so
    that the tracks held out of the data are never driven in training."""

    if config.ego_tracks or windows is None:
        return config
    from gridsim.envs.gridsim_env import GridSimEnv
    from gridsim.scenario.collection import is_collection
    from gridsim.scenario.families.recorded import scene_of
    from gridsim.scenario.family import family_of
    from gridsim.traffic.track import scene_ids, track_name

    recorded = [sc for sc in GridSimEnv(config.scenario).scenarios if family_of(sc).recorded]
    if not recorded:
        return config
    names = sorted(np.unique(windows.track).tolist())
    scenes = [scene_of(sc) for sc in recorded]
    per_scene = {scene: scene_ids(names, scene) for scene in scenes}
    missing = [scene for scene, ids in per_scene.items() if not ids]
    if missing:
        raise RunError(f"--pretrain {config.pretrain} has no track of scene "
                       f"{', '.join(map(repr, missing))}, which {config.scenario!r} replays: "
                       "record windows of that scene")  # fmt: skip
    if not is_collection(config.scenario):
        return config.replace(ego_tracks=tuple(per_scene[scenes[0]]))
    return config.replace(
        ego_tracks=tuple(track_name(scene, i) for scene, ids in per_scene.items() for i in ids),
    )


def _read_npz(path: Path, *keys: str) -> tuple[np.ndarray, ...] | None:
    """The arrays ``keys`` of the file ``path``, or None if there is no such file; a
    :class:`RunError` naming the file if it cannot be read."""
    if not path.exists():
        return None
    try:
        with np.load(path) as data:
            return tuple(data[k] for k in keys)
    except Exception as exc:
        raise RunError(f"{path}: not a readable .npz archive of a run (damaged or replaced?): "
                       f"{type(exc).__name__}: {exc}") from None  # fmt: skip


def _score(index: int, fitness: np.ndarray, stats: dict) -> dict:
    """A member's fitness and lost share on some episodes, as the history keeps it."""
    return {"index": index, "l1": float(fitness[0]), "l2": float(fitness[1]),
            "l3": float(fitness[2]), "violation": float(stats.get("lost", 0.0))}  # fmt: skip
