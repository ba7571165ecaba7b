"""The paper's comparison: NeuroTrajectory against DWA, End2End and constant velocity.

The baselines: constant velocity, the destination curve (the feasible arc to the given
destination, no grid: the floor when the destination is known), DWA and End2End.

**Open loop.** For every scenario group (:data:`~neurotrajectory.data.windows.GROUPS`), the
labelled windows are split by track; End2End is trained on the train split, and every method
predicts the held-out windows, scored by :mod:`neurotrajectory.compare.metrics`. NeuroTrajectory is
represented by one member of its Pareto front chosen **without** the test data (``pick``,
the knee by default), and also by the front member with the lowest test RMSE (an optimistic
pick, labelled as such).

**Closed loop.** Every method drives GridSim-v0 on each scenario of the group (on a
recorded scene, each track of the test side of the split, and no scene without one):
NeuroTrajectory, DWA and constant velocity through the trajectory action, End2End through
its discrete commands, and the human reference for scale. Reported: completion (the
episode ran to its time limit or destination without collision or leaving the road),
progress (distance driven over the distance the human reference drove in the same time),
collisions, off-road, mean speed, mean steering rate and the episode fitness vector ``[l1,
l2, l3]``.
"""

from __future__ import annotations

import json
import re
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, ClassVar

import numpy as np
from pydantic import Field, model_validator

from gridsim.errors import WorkKept, warn_data
from gridsim.outputs import (
    empty_folder,
    interrupted,
    new_folder,
    progress_bar,
    write_json,
)
from gridsim.policies import Reference
from gridsim.scenario.collection import input_changes, same_inputs, scenario_files
from gridsim.scenario.loader import load_scenario
from gridsim.scenario.schema import MAX_DURATION
from gridsim.seeding import Salt, stream
from neurotrajectory.compare import methods
from neurotrajectory.compare.baselines.end2end import CommandPolicy, End2End, TrainSettings
from neurotrajectory.compare.closed_loop import closed_loop, summarise
from neurotrajectory.compare.front import NetPredictor, load_front, trained_tracks
from neurotrajectory.compare.methods import NT_BEST, NT_PICKED
from neurotrajectory.compare.metrics import Accuracy, accuracy
from neurotrajectory.compare.predictors import Setting, TrajectoryPolicy
from neurotrajectory.data.recording import group_inputs, record_dataset
from neurotrajectory.data.storage import check_new_folder, dataset_manifest, load_split
from neurotrajectory.data.windows import (
    GROUPS,
    DatasetError,
    Windows,
    bar_callbacks,
    group_scenarios,
    recording_mismatch,
    recording_settings,
)
from neurotrajectory.evolve.pareto import PICKS, pick_member
from neurotrajectory.settings import Bool, Integer, OneOf, Real, Seed, Settings

#: A group's name: it names folders of the output (``data/NAME``, ``models/end2end-NAME``).
GROUP_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,63}")


class EvalConfig(Settings):
    """What an evaluation records, trains and runs (saved as ``eval_config.json``). Each
    field's description is its ``evaluate`` flag's help."""

    Error: ClassVar[type[Exception]] = DatasetError

    groups: tuple[str, ...] = Field(
        tuple(GROUPS), description="the scenario groups compared: built-in groups and the "
        "names of sources")  # fmt: skip
    episodes: Annotated[Integer, Field(ge=1)] = Field(
        8, description="episodes recorded per generated scenario"
    )
    episode_seconds: Annotated[Real, Field(gt=0, le=MAX_DURATION)] = Field(
        30.0, description="length of each recorded episode [s]"
    )
    test_fraction: Annotated[Real, Field(gt=0, lt=1)] = Field(
        0.3, description="share of each group's tracks held out for testing"
    )
    seed: Seed = Field(0, description="seed of the split and episodes")
    pick: Annotated[str, OneOf(PICKS)] = Field(
        "knee", description="the front member compared (picked without test data)"
    )
    end2end: TrainSettings = Field(default_factory=TrainSettings)
    closed_loop_episodes: Annotated[Integer, Field(ge=0)] = Field(
        3, description="closed-loop episodes per scenario (0: skip)"
    )
    closed_loop_seconds: Annotated[Real, Field(gt=0, le=MAX_DURATION)] = Field(
        20.0, description="length of each closed-loop episode [s]"
    )
    videos: Bool = Field(
        False, description="export each method's first closed-loop episode to <out>/videos/"
    )
    sources: dict[str, str] = Field(
        default_factory=dict, description="groups of the user's scenarios: name -> folder or "
        "glob of scenario files")  # fmt: skip
    goal_seconds: Annotated[Real, Field(gt=0)] | None = Field(
        None,
        description="how far ahead every planner's destination lies [s] "
        "(env.goal_seconds; default: at the last set-point, where the human will be)",
    )

    @model_validator(mode="after")
    def _groups(self) -> EvalConfig:
        unknown = [g for g in self.groups if g not in GROUPS and g not in self.sources]
        if unknown:
            raise ValueError(f"unknown scenario groups {unknown}; choose from {list(GROUPS)} "
                             "or give NAME=FOLDER")  # fmt: skip
        shadowing = sorted(set(self.sources) & set(GROUPS))
        if shadowing:
            raise ValueError(f"--group {shadowing[0]}=...: {shadowing[0]!r} is a built-in group "
                             "(its title and source would be claimed for your files); give "
                             "yours another name")  # fmt: skip
        bad = [g for g in self.groups if not GROUP_NAME.fullmatch(g)]
        if bad:
            raise ValueError(f"group name {bad[0]!r}: use letters, digits, '_', '-', '.', "
                             "starting with a letter or digit (it names folders)")  # fmt: skip
        return self


@dataclass
class GroupResult:
    group: str
    source: str
    train_windows: int
    test_windows: int
    test_tracks: int
    accuracy: dict[str, Accuracy]
    closed_loop: dict[str, dict]
    best_member: int
    #: the set-points' times after the decision [s]
    setpoint_times: tuple[float, ...] = ()
    #: test tracks that the run trained on (``SCENE/ID``): its figures there are not held out
    trained_test_tracks: tuple[str, ...] = ()


def _given_dataset(group: str, cfg: EvalConfig, data_dir: Path) -> dict:
    """The manifest of the group's dataset in ``data_dir/<group>`` (``--data``), checked: a
    :class:`DatasetError` naming the folder and what to do if there is none, or it holds one
    side of a split, other files' windows or another goal's."""
    folder = data_dir / group
    if not (folder / "manifest.json").is_file():
        source = cfg.sources.get(group, group)
        named = "" if source == group else f" --name {group}"
        goal = "" if cfg.goal_seconds is None else f" --goal-seconds {cfg.goal_seconds:g}"
        raise DatasetError(f"--data {data_dir}: no dataset of the group {group} ({folder} "
                           f"has no manifest.json): record it there (neurotrajectory record "
                           f"--scenario {source}{named} --episodes {cfg.episodes} "
                           f"--episode-seconds {cfg.episode_seconds:g} --seed {cfg.seed}"
                           f"{goal} --out {folder}), evaluate only the groups recorded "
                           "(--groups ...), or leave out --data")  # fmt: skip
    manifest = dataset_manifest(folder)
    if "split" in manifest:
        raise DatasetError(
            f"{folder}: holds only the {manifest['split']['side']} side of a split "
            "(record --split); evaluation needs the whole group's windows"
        )
    problem = _other_files(manifest, group, cfg.sources.get(group))
    if problem:
        raise DatasetError(f"{folder}: {problem}: record it from the group's files (or leave "
                           "out --data: evaluate records what it needs)")  # fmt: skip
    if manifest.get("goal_seconds") != cfg.goal_seconds:
        raise DatasetError(f"{folder}: recorded with goal_seconds "
                           f"{manifest.get('goal_seconds')}, the evaluation asks "
                           f"{cfg.goal_seconds}: record it with the same "
                           "--goal-seconds")  # fmt: skip
    return manifest


def _check_groups(fronts: dict[str, Front], cfg: EvalConfig, data_dir: Path | None) -> None:
    """Every group's dataset (``--data``) or scenarios checked against its run before
    anything is recorded, trained or written: a :class:`DatasetError` naming the group, the
    run and the settings its windows would have other than the run's
    (:func:`~neurotrajectory.data.windows.recording_mismatch`)."""
    for group, front in fronts.items():
        if data_dir is not None:
            settings = _given_dataset(group, cfg, data_dir)
        else:
            first = group_scenarios(group, cfg.sources.get(group))[0]
            settings = recording_settings(load_scenario(first).config)
        problem = recording_mismatch(settings, front.scenario_config)
        if problem:
            said = problem.replace("record them from", "evaluate it on")
            raise DatasetError(f"{group}: the run {front.run.out} does not fit the group's "
                               f"scenarios: {said}")  # fmt: skip


def _split_dataset(
    group: str, cfg: EvalConfig, data_dir: Path | None, out: Path, log, progress: bool = True,
    *, checked: bool = False,
) -> tuple[dict, Windows, Windows]:  # fmt: skip
    """The group's manifest and its windows split by track (``train``, ``test``): from
    ``data_dir/<group>`` if given (checked by :func:`_given_dataset` unless ``checked``
    already: it hashes every input file), else recorded into ``out`` first. Each window is
    read once (:func:`~neurotrajectory.data.storage.load_split`)."""
    if data_dir is not None:
        if not checked:
            _given_dataset(group, cfg, data_dir)
        folder = data_dir / group
    else:
        folder = out / "data" / group
        if (folder / "manifest.json").is_file():  # recorded before a break: if still the same
            problem = _other_files(dataset_manifest(folder), group, cfg.sources.get(group))
            if problem is None:
                return _split(folder, group, cfg)
            log(f"{group}: recording again: the windows kept were {problem}")
            shutil.rmtree(folder)
        log(f"{group}: recording windows")
        with progress_bar(desc=f"record {group}", unit="episode", leave=False,
                          disable=not progress) as bar:  # fmt: skip
            # written as recorded, then read back; with checkpoints from which the same
            # command goes on if it is interrupted
            def record() -> None:
                record_dataset(folder, group, cfg.episodes, cfg.seed,
                               duration=cfg.episode_seconds, source=cfg.sources.get(group),
                               goal_seconds=cfg.goal_seconds, resume=True, log=log,
                               **bar_callbacks(bar))  # fmt: skip

            try:
                record()
            except WorkKept as exc:  # (the settings are the same: its files changed)
                log(f"{group}: recording again: {exc}")
                shutil.rmtree(folder)
                bar.reset()
                bar.total = None  # (the files planned again count it anew)
                record()
    return _split(folder, group, cfg)


def _split(folder: Path, group: str, cfg: EvalConfig) -> tuple[dict, Windows, Windows]:
    """:func:`~neurotrajectory.data.storage.load_split` of ``group``'s dataset ``folder``; a
    group too small to split says which and how to grow it."""
    try:
        return load_split(folder, cfg.test_fraction, cfg.seed)
    except DatasetError as exc:
        if "to split" not in str(exc):
            raise
        raise DatasetError(
            f"{group}: {exc}: the split by track holds whole tracks out; "
            "record more of the group (--episodes)"
        ) from None


def _other_files(manifest: dict, group: str, source: str | None) -> str | None:
    """Why the dataset of ``manifest`` does not hold the windows of the group ``group`` (the
    scenario files ``source``; None: a built-in group), or None: it was recorded from other
    scenarios (compared by file name, so that a folder may move), or from files whose
    contents changed since (the manifest's ``inputs``, where it has them)."""

    def names(paths) -> set[str]:
        return {Path(str(p)).name for p in paths}

    recorded = names(m.get("scenario", "") for m in manifest.get("scenarios", []))
    skipped = names(s.get("file", "") for s in manifest.get("skipped", []))
    if source is None and group in GROUPS:
        files = names(GROUPS[group])
    else:  # every file of the folder or glob, usable or not (nothing is built)
        ref = group if source is None else source
        files = names(scenario_files(ref) or [ref])
    if not recorded <= files or not files <= recorded | skipped:

        def listed(found: set[str]) -> str:
            return ", ".join(sorted(found)[:3]) + (", ..." if len(found) > 3 else "")

        return (f"recorded from {listed(recorded)}, not from the files of the group {group} "
                f"({listed(files)})")  # fmt: skip
    stamps = manifest.get("inputs")
    if isinstance(stamps, dict):
        now = group_inputs(group, source)
        if not same_inputs(stamps, now):
            changes = input_changes(stamps, now) or "a file moved or renamed"
            return f"recorded from files that have changed since ({changes})"
    return None


@dataclass(frozen=True)
class Front:
    """A trained run's Pareto front: networks and the member picked without test data."""

    run: object
    nets: list
    picked: int

    @property
    def scenario_config(self):
        """The run's scenario configuration (of a collection, its first member's): the
        settings its network was trained in."""
        from gridsim.scenario.collection import load_collection

        return load_collection(self.run.config.scenario)[0].config

    def info(self, pick: str) -> dict:
        c = self.run.config
        return {"run": str(self.run.out), "scenario": c.scenario, "preset": c.preset,
                "population": c.population, "generations": c.generations,
                "episodes": c.episodes, "episode_seconds": c.episode_seconds,
                "front_size": len(self.nets), "picked_member": self.picked,
                "pick": pick, "goal_seconds": c.goal_seconds}  # fmt: skip


def _load_fronts(runs: dict[str, str | Path], pick: str) -> dict[str, Front]:
    loaded: dict[str, Front] = {}
    out = {}
    for group, run_dir in runs.items():
        key = str(Path(run_dir).resolve())
        if key not in loaded:
            run, fitness, _, nets = load_front(run_dir)
            loaded[key] = Front(run, nets, pick_member(fitness, pick))
        out[group] = loaded[key]
    return out


def _evaluate_group(
    group: str,
    data: tuple[dict, Windows, Windows],
    front: Front,
    cfg: EvalConfig,
    out: Path,
    log,
    progress: bool = True,
) -> GroupResult:
    """One group's scores: ``data`` is its manifest and ``(train, test)`` windows."""
    manifest, train, test = data
    test_tracks = set(test.track.tolist())
    seen = sorted(test_tracks & trained_tracks(front.run.config))
    if seen:  # the run drove these as the ego in training: its scores on them are not held out
        from neurotrajectory.compare.report import not_held_out

        said = not_held_out(group, seen, len(test_tracks))
        warn_data(f"{said} ({front.run.out}); evaluate it on scenes the run did not train on")
    setting = Setting.from_manifest(manifest)
    log(f"{group}: {len(train)} train / {len(test)} test windows; training End2End")
    e2e = End2End.train(train, setting, cfg.end2end, progress=progress)
    e2e.save(out / "models" / f"end2end-{group}")
    picked = front.nets[front.picked]
    nt = NetPredictor(picked)
    planners = {cls.name: cls(setting) for cls in methods.PLANNERS}
    compared = {**planners, End2End.name: e2e}
    log(
        f"{group}: scoring {len(compared)} methods and {len(front.nets)} front members on "
        f"{len(test)} test windows"
    )
    to_score = [*compared.items(), *((f"member {k}", NetPredictor(n))
                                    for k, n in enumerate(front.nets))]  # fmt: skip
    scored = progress_bar(to_score, desc=f"score {group}", unit="method", leave=False,
                          disable=not progress)  # fmt: skip
    scores, members = {}, []
    for name, m in scored:
        scored.set_postfix(method=name)
        a = accuracy(m.predict(test), test.target, test.heading)
        if name in compared:
            scores[name] = a
        else:
            members.append(a)
    best = int(np.argmin([a.rmse for a in members]))
    scores[NT_PICKED] = members[front.picked]
    scores[NT_BEST] = members[best]
    loop = {}
    if cfg.closed_loop_episodes:
        policies = {"human reference": Reference()}
        # every trajectory planner's plans are followed alike: smoothed as the network's
        keep = picked.cfg.smoothing
        policies |= {n: TrajectoryPolicy(p, keep) for n, p in planners.items()}
        policies |= {End2End.name: CommandPolicy(e2e), NT_PICKED: TrajectoryPolicy(nt, keep)}
        rng = stream(cfg.seed, Salt.CLOSED_LOOP_EPISODES)
        seeds = [int(s) for s in rng.integers(0, 2**31 - 1, size=cfg.closed_loop_episodes)]
        held = _closed_loop_tracks(group_scenarios(group, cfg.sources.get(group)), test_tracks,
                                   cfg.closed_loop_episodes, log)  # fmt: skip
        scenarios = list(held)
        episodes = sum(len(seeds) if ids is None else len(ids) for ids in held.values())
        bar = progress_bar(
            policies.items() if scenarios else (),
            unit="method",
            leave=False,
            disable=not progress,
            desc=f"closed loop {group} ({episodes} episodes each)",
        )
        for name, policy in bar:
            slug = name.lower().replace(" ", "-")
            per = [closed_loop(sc, policy, seeds[: len(held[sc]) if held[sc] else None],
                               cfg.closed_loop_seconds,
                               out / "videos" / f"{group}-{Path(sc).stem}-{slug}.mp4"
                               if cfg.videos else None, cfg.goal_seconds,
                               label=_video_label(name, group, sc), tracks=held[sc])
                   for sc in scenarios]  # fmt: skip
            # every episode's outcome, to look up the failures (results.json); the means
            # over all of them (scenes may give different numbers of held-out tracks)
            rows = [
                {"scenario": Path(sc).stem, **row}
                for sc, p in zip(scenarios, per, strict=True)
                for row in p["per_episode"]
            ]
            loop[name] = summarise(rows) | {"per_episode": rows}
    return GroupResult(group, manifest["source"], len(train), len(test),
                       len(test_tracks), scores, loop, best,
                       tuple(float(t) for t in setting.times), tuple(seen))  # fmt: skip


def _closed_loop_tracks(scenarios: tuple[str, ...], test_tracks: set[str], episodes: int,
                        log) -> dict[str, list[str] | None]:  # fmt: skip
    """Per scenario of a group, what its closed loop drives: on a recorded scene the tracks
    of the test side of the split (``test_tracks``, ``SCENE/ID``), each once, at most
    ``episodes`` of them in the scene's order (a random ego would mostly drive the tracks
    End2End and the run trained on); None on a generated one (episodes drawn from seeds).
    A recorded scene none of whose tracks is on the test side is left out, and said."""
    from gridsim.scenario.families.recorded import recorded_scene, scene_of
    from gridsim.scenario.family import is_recorded
    from gridsim.traffic.track import track_name

    out: dict[str, list[str] | None] = {}
    for sc in scenarios:
        scenario = load_scenario(sc)
        if not is_recorded(scenario):
            out[sc] = None
            continue
        scene = scene_of(scenario)
        ids = [t.track_id for t in recorded_scene(scenario)[1]
               if track_name(scene, t.track_id) in test_tracks]  # fmt: skip
        if ids:
            out[sc] = ids[:episodes]
        else:
            log(f"{sc}: no track of the test side to drive in closed loop; left out")
    return out


def evaluate(
    run_dir: str | Path,
    out: str | Path,
    cfg: EvalConfig = EvalConfig(),
    data_dir: str | Path | None = None,
    log=print,
    group_runs: dict[str, str | Path] | None = None,
    progress: bool = True,
) -> list[GroupResult]:
    """Run the whole comparison; writes tables, plots and models into ``out``.
    NeuroTrajectory is the run in ``run_dir``, or for the groups in ``group_runs`` the run
    given there."""
    from neurotrajectory.compare.report import write_report

    out = Path(out)
    check_new_folder(out)  # before loading anything; new_folder checks again under its lock
    group_runs = dict(group_runs or {})
    unknown = sorted(set(group_runs) - set(cfg.groups))
    if unknown:
        raise DatasetError(f"runs given for groups {unknown} that are not evaluated")
    runs = {g: group_runs.get(g, run_dir) for g in cfg.groups}
    fronts = _load_fronts(runs, cfg.pick)  # fails before anything is written
    for group, front in fronts.items():
        trained = front.run.config.goal_seconds
        if trained != cfg.goal_seconds:
            said = "at the last set-point" if trained is None else f"{trained:g} s ahead"
            how = "leave out --goal-seconds" if trained is None else (
                f"give --goal-seconds {trained:g}")  # fmt: skip
            raise DatasetError(f"{group}: the run {front.run.out} was trained with the "
                               f"destination {said}; {how} to evaluate it in its setting (or "
                               "train a run for this one)")  # fmt: skip
    data_dir = Path(data_dir).absolute() if data_dir is not None else None
    _check_groups(fronts, cfg, data_dir)  # each group before any is recorded or scored
    settings = {"neurotrajectory": {g: f.info(cfg.pick) for g, f in fronts.items()},
                **cfg.as_dict(), "data": None if data_dir is None else str(data_dir)}  # fmt: skip
    if data_dir is not None:  # the windows are the datasets' (their manifests say how made)
        settings.update(episodes=None, episode_seconds=None)
    # out appears, whole, when everything is written; interrupted, the hidden folder keeps
    # the windows recorded, and the same command goes on with them
    with new_folder(out, resumable=True) as partial:
        _go_on_or_start(partial, json.loads(json.dumps(settings)), log)
        write_json(partial / "eval_config.json", settings)
        results = []
        try:
            for group in cfg.groups:
                t0 = time.perf_counter()
                data = _split_dataset(
                    group, cfg, data_dir, partial, log, progress, checked=True
                )  # (by _check_groups)
                result = _evaluate_group(group, data, fronts[group], cfg, partial, log, progress)
                del data  # (the next group's windows are read without these)
                results.append(result)
                rmse = ", ".join(f"{k} {v.rmse:.2f}" for k, v in result.accuracy.items())
                log(f"{group}: done in {time.perf_counter() - t0:.0f} s; RMSE {rmse}")
        except BaseException as exc:
            if interrupted(exc):
                _say_kept(partial)
            raise
        write_report(results, partial, {g: f.info(cfg.pick) for g, f in fronts.items()})
    return results


def _video_label(method: str, group: str, scenario: str) -> str:
    """Who drives an evaluation video, and where: ``"End2End, urban (lankershim_1_1)"``; a
    group of one scenario of its name is named once."""
    stem = Path(scenario).stem
    return f"{method}, {group}" + ("" if stem == group else f" ({stem})")


#: The settings the windows an evaluation records depend on (each group's files are checked
#: on their own, :func:`_split_dataset`): an interrupted evaluation goes on with its windows
#: when only others changed (the closed loop, End2End, the runs, the split, ...).
RECORDING_SETTINGS = ("episodes", "episode_seconds", "seed", "goal_seconds")
#: The ``evaluate`` flags of settings not named by the rule (``a_b``: ``--a-b``).
_FLAGS = {"end2end": "--e2e-epochs", "neurotrajectory": "--run/--group-run",
          "sources": "--group", "groups": "--groups"}  # fmt: skip


def _go_on_or_start(partial: Path, settings: dict, log) -> None:
    """Keep what an interrupted evaluation left in ``partial`` (the windows it recorded,
    ``data/``; the rest is made again) if it recorded them with the same
    :data:`RECORDING_SETTINGS`, or refuse to discard them (:class:`~gridsim.errors.WorkKept`,
    naming the flags that differ), or clear what a killed one left."""
    config = partial / "eval_config.json"
    if not config.is_file():
        empty_folder(partial)
        return
    try:
        then = json.loads(config.read_text())
    except (OSError, ValueError):
        then = None
    if not isinstance(then, dict):
        raise WorkKept(f"{partial} holds an interrupted evaluation whose eval_config.json is "
                       f"unreadable: remove {partial} to start afresh")  # fmt: skip
    differ = sorted(k for k in set(settings) | set(then) if then.get(k) != settings.get(k))
    kept = sorted(p.name for p in (partial / "data").glob("*") if p.is_dir())
    recording = [k for k in differ if k in RECORDING_SETTINGS]
    if recording and kept and settings.get("data") is None:  # (with --data none is read)
        raise WorkKept(f"{partial} holds the windows of an interrupted evaluation recorded "
                       f"with other {_flags(recording)}: give the values it was made with to "
                       f"go on with them, or remove {partial} to start afresh")  # fmt: skip
    empty_folder(partial, keep=("data", "eval_config.json"))
    if kept:
        changed = f" ({_flags(differ)} changed: the rest is made again)" if differ else ""
        log(f"going on with the interrupted evaluation in {partial}: the windows recorded "
            f"of {', '.join(kept)} are kept{changed}")  # fmt: skip


def _flags(settings: list[str]) -> str:
    """The ``evaluate`` flags of ``eval_config.json``'s ``settings``."""
    return ", ".join(_FLAGS.get(k, "--" + k.replace("_", "-")) for k in settings)


def _say_kept(partial: Path) -> None:
    """What an interrupted evaluation leaves in ``partial`` for the same command to go on
    with (nothing, and ``partial`` is removed, if it recorded no window)."""
    if not any((partial / "data").glob("*")):
        shutil.rmtree(partial, ignore_errors=True)
        return
    print(
        f"neurotrajectory: the windows recorded so far are kept in {partial}: the same "
        "command goes on with them (remove that folder to start afresh)",
        file=sys.stderr,
    )
