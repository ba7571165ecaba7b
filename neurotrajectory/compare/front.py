"""Picking and driving members of a trained Pareto front."""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from gridsim.envs.gridsim_env import GridSimEnv
from gridsim.errors import warn_data
from gridsim.outputs import folder_holder, progress_bar
from gridsim.scenario.schema import Scenario
from gridsim.traffic.track import track_name
from neurotrajectory.data.windows import goal_overrides, has_recorded
from neurotrajectory.evolve.fitness import scenario_net_config
from neurotrajectory.evolve.genome import genome_mismatch, set_genome
from neurotrajectory.evolve.pareto import pick_member
from neurotrajectory.evolve.runs import Run, RunError
from neurotrajectory.model import (
    NetConfig,
    NetPolicy,
    TrajectoryNet,
    one_thread,
    size_mismatch,
    window_inputs,
)


class NetPredictor:
    """A NeuroTrajectory network as a predictor of set-points for labelled windows."""

    def __init__(self, net: TrajectoryNet, name: str = "NeuroTrajectory") -> None:
        self.net = net.eval()
        self.name = name

    @torch.no_grad()
    @one_thread()
    def predict(self, batch, chunk: int = 128) -> np.ndarray:
        problem = size_mismatch(self.net.cfg, batch)
        if problem:
            raise RunError(problem)
        out = []
        for start in range(0, len(batch), chunk):
            sl = slice(start, start + chunk)
            inputs = window_inputs(batch, np.arange(len(batch))[sl])
            out.append(self.net(*inputs).numpy().astype(np.float64))
        return np.concatenate(out)


def load_front(run_dir: str | Path) -> tuple[Run, np.ndarray, np.ndarray, list[TrajectoryNet]]:
    """The run, its front's fitness ``(M, 3)`` and genomes, and one network per member."""
    run = Run.open(run_dir)
    run.warn_changed_inputs()
    path = run.out / "front.npz"
    if not path.exists():
        holder = folder_holder(run.out)
        if holder:
            raise RunError(f"{run.out}: no front.npz yet: the run is being trained ({holder}); "
                           "its front is chosen when it ends")  # fmt: skip
        raise RunError(f"{run.out}: no front.npz (the run has not finished, or the file was "
                       f"removed): `neurotrajectory train --resume {run.out}` chooses it from "
                       "the last generation")  # fmt: skip
    try:
        with np.load(path) as data:
            genomes, fitness = data["genomes"], data["fitness"]
            base = NetConfig.from_dict(json.loads(str(data["net"])))
    except (OSError, EOFError, KeyError, ValueError, TypeError, zipfile.BadZipFile) as exc:
        raise RunError(f"{path}: unreadable front ({type(exc).__name__}: {exc}); "
                       f"`neurotrajectory train --resume {run.out}` chooses it again from the "
                       "last generation") from None  # fmt: skip
    _say_if_unfinished(run)
    cfg = scenario_net_config(run.config.scenario, run.config.overrides, base)
    return run, fitness, genomes, [_net(cfg, genome, path) for genome in genomes]


def _say_if_unfinished(run: Run) -> None:
    """A :class:`~gridsim.errors.DataWarning` when the run's front is of fewer generations
    than it is set to train (``train --resume RUN --generations N`` stopped before its end:
    the front is the one chosen before, and results of it are not the longer run's)."""
    try:
        chosen = json.loads((run.out / "front.json").read_text())["generation"] + 1
    except (OSError, ValueError, KeyError, TypeError):
        return  # (an older run's front.json: nothing to compare)
    if chosen < run.config.generations:
        warn_data(f"{run.out}: its front was chosen after generation {chosen}, but the run is "
                  f"set to {run.config.generations} (extended, and stopped before its end): "
                  f"this is the earlier front; `neurotrajectory train --resume {run.out}` "
                  "finishes the run")  # fmt: skip


def _net(cfg: NetConfig, genome: np.ndarray, path: Path) -> TrajectoryNet:
    """A network of ``cfg`` with the weights ``genome`` (read from ``path``)."""
    net = TrajectoryNet(cfg)
    problem = genome_mismatch(net, genome.shape[-1])
    if problem:
        raise RunError(f"{path}: {problem}")
    set_genome(net, genome)
    return net.eval()


def load_warm_start(run: Run, smoothing: float | None = None) -> NetPolicy | None:
    """A policy for the run's warm start (generation 0's parent; its plans smoothed as the
    run's, or by ``smoothing``), or None for a run without one."""
    genome = run.warm_start_genome()
    if genome is None:
        if run.config.warm_started:  # it had one: removed
            warn_data(f"{run.out / 'warm_start.npz'} is missing: the run's warm start is not "
                      "driven beside its members (restore it from a copy of the run to "
                      "compare them)")  # fmt: skip
        return None
    cfg = scenario_net_config(run.config.scenario, run.config.overrides, run.net_config)
    return NetPolicy(_net(cfg, genome, run.out / "warm_start.npz"), smoothing)


def load_front_member(
    run_dir: str | Path, pick: str, smoothing: float | None = None
) -> tuple[Run, NetPolicy, dict]:
    """The run, a policy for the chosen front member (its plans smoothed as the run's, or by
    ``smoothing``), and that member's fitness."""
    run, fitness, _, nets = load_front(run_dir)
    k = pick_member(fitness, pick)
    member = {  # "member": its place in the front, as front.json's "member" says it
        "pick": pick,
        "member": k,
        "l1": float(fitness[k, 0]),
        "l2": float(fitness[k, 1]),
        "l3": float(fitness[k, 2]),
    }
    return run, NetPolicy(nets[k], smoothing), member


def heldout(
    run_dir: str | Path,
    episodes: int,
    pick: str = "knee",
    seconds: float | None = None,
    smoothing: float | None = None,
    progress: bool = False,
) -> dict:
    """Closed-loop statistics of the picked front member on ``episodes`` episodes that no
    generation trained on (:meth:`~neurotrajectory.evolve.runs.TrainConfig.heldout_seeds`; on a
    recorded scene trained on some ``ego_tracks``, each of the scene's other tracks that can
    be the ego once, at most ``episodes`` of them in id order), each ``seconds`` long
    (default: as long as the training episodes), beside the destination curve's and, if the
    run has one, its warm start's (``"warm_start"``: what evolution started from; ``"paired"``:
    the two compared on the episodes both complete, :func:`paired_l1`) on the same episodes,
    all plans smoothed alike: as the run's, or by ``smoothing``. ``progress``: a bar over the
    episodes of all planners."""
    from neurotrajectory.compare.baselines.destination_curve import DestinationCurve
    from neurotrajectory.compare.closed_loop import drive_episodes, summarise
    from neurotrajectory.compare.predictors import Setting, TrajectoryPolicy

    run, policy, member = load_front_member(run_dir, pick, smoothing)
    cfg = run.config
    seconds = cfg.episode_seconds if seconds is None else float(seconds)
    tracks, names = None, []
    if cfg.ego_tracks:  # each held-out track of the run's scenes once
        split = run_tracks(cfg)
        tracks = split.held[:episodes]
        names = _track_names(tracks, split.scenes)
    seeds = list(cfg.heldout_seeds(len(tracks) if tracks else episodes))
    warm = load_warm_start(run, policy.keep)
    planners = 2 if warm is None else 3
    bar = progress_bar(total=planners * len(seeds), desc="held-out episodes", unit="episode",
                       leave=False, disable=not progress)  # fmt: skip

    def drive(planner) -> list[dict]:
        if tracks is None:
            return drive_episodes(cfg.scenario, planner, seeds, seconds,
                                  goal_seconds=cfg.goal_seconds, progress=bar.update)  # fmt: skip
        return [{**row, "track": name}  # each held-out track once, on its own scene
                for (ref, track), name, seed in zip(tracks, names, seeds, strict=True)
                for row in drive_episodes(ref, planner, [seed], seconds, ego={"track": track},
                                          goal_seconds=cfg.goal_seconds,
                                          progress=bar.update)]  # fmt: skip

    with bar:
        rows = drive(policy)
        env = GridSimEnv(cfg.scenario, **cfg.overrides)
        keep = policy.keep  # the curve's plans are smoothed as the member's
        baseline = drive(TrajectoryPolicy(DestinationCurve(Setting.from_env(env)), keep))
        started = None if warm is None else drive(warm)
    return {
        "member": member,
        "episode_seconds": seconds,
        "plan_smoothing": keep,
        **({"ego_tracks": names} if tracks else {}),
        "seeds": seeds,
        "network": summarise(rows),
        **({"warm_start": summarise(started)} if started else {}),
        **({"paired": paired_l1(rows, started)} if started else {}),
        DestinationCurve.name: summarise(baseline),
        "episodes": rows,
        **({"warm_start_episodes": started} if started else {}),
    }


def _scenes(scenario: str) -> list[tuple[str, Scenario]]:
    """``(file, scenario)`` of each scene a run of ``scenario`` drives: ``scenario`` itself
    for one scene, each usable file of a collection (as a run loads it; the others are named
    in a warning)."""
    from gridsim.scenario.collection import load_usable

    return load_usable(scenario)[0]


def _recorded(scenes: list[tuple[str, Scenario]]) -> list[tuple[str, Scenario]]:
    """The ``(file, scenario)`` of ``scenes`` that replay recorded tracks (a collection may
    have generated ones beside them)."""
    from gridsim.scenario.family import family_of

    return [(ref, sc) for ref, sc in scenes if family_of(sc).recorded]


def _track_names(tracks: list[tuple[str, str]], scenes: list[tuple[str, Scenario]]) -> list[str]:
    """How reports name ``(scenario file, track id)`` pairs of ``scenes``
    (:func:`_scenes`): the id on one scene, ``FILE/ID`` on a collection (a track id may be on
    several)."""
    several = len(scenes) > 1
    return [track_name(ref, track) if several else track for ref, track in tracks]


@dataclass(frozen=True)
class RunTracks:
    """The recorded tracks of a run's scenes that can be the ego, as ``(scenario file, track
    id)``: those it trained on and those held out from it (:func:`run_tracks`)."""

    scenes: list[tuple[str, Scenario]]  # (file, scenario) of each scene (:func:`_scenes`)
    trained: list[tuple[str, str]]  # the run's ego_tracks that can be the ego
    held: list[tuple[str, str]]  # every other one, in id order (what heldout drives)


def run_tracks(config) -> RunTracks:
    """The training and held-out tracks of a run of ``config`` (a
    :class:`~neurotrajectory.evolve.runs.TrainConfig` with ``ego_tracks``, on recorded
    scenes); a :class:`RunError` when none is held out."""
    scenes = _scenes(config.scenario)
    trained = []
    for name in config.ego_tracks:  # (the ones that can be the ego: the run drove no other)
        try:
            trained.append(_resolve_track(config.scenario, name, scenes))
        except RunError:
            continue
    return RunTracks(scenes, trained, _other_tracks(config.scenario, config.ego_tracks, scenes))


def _resolve_track(
    scenario: str, name: str, scenes: list[tuple[str, Scenario]] | None = None
) -> tuple[str, str]:
    """``(scenario file, track id)`` of the track ``name`` of ``scenario`` (``scenes`` if
    loaded already, :func:`_scenes`) that can be the ego: named as reports name it
    (:func:`_track_names`), as ``SCENE/ID`` with the scene's id (as ``config.json`` and
    datasets name it), or by its id alone where one scene has it."""
    from gridsim.scenario.families.recorded import scene_of

    scenes = _recorded(_scenes(scenario) if scenes is None else scenes)
    every = _other_tracks(scenario, (), scenes)
    scene_ids = {ref: scene_of(sc) for ref, sc in scenes}
    names: dict[str, list[tuple[str, str]]] = {}
    for ref, track in every:
        for alias in {track_name(ref, track), track_name(scene_ids[ref], track), track}:
            names.setdefault(alias, []).append((ref, track))
    found = names.get(name, [])
    if len(found) == 1:
        return found[0]
    if found:
        named = ", ".join(track_name(r, t) for r, t in found)
        raise RunError(f"--track {name}: a track of {len(found)} scenes of {scenario}; name "
                       f"one as FILE/ID: {named}")  # fmt: skip
    like = ", ".join(_track_names(every, scenes)[:3])
    raise RunError(f"--track {name}: not a track of {scenario} that can be the ego ({len(every)} "
                   f"are, named like {like}, as heldout.json names them)")  # fmt: skip


def episode_env(
    run: Run, seconds: float | None = None, track: str | None = None, **kwargs
) -> GridSimEnv:
    """An environment for the run's episodes as :func:`heldout` drives them: ``seconds`` long
    (default: the run's episode length), the ego driving the recorded ``track`` (named as a
    held-out report names it: the id, or ``FILE/ID`` on a collection of scenes; default: the
    run's training tracks, if any); ``kwargs`` go to :class:`GridSimEnv`."""
    cfg = run.config
    duration = {"simulation": {"duration": cfg.episode_seconds if seconds is None else seconds}}
    if track is None:
        return GridSimEnv(cfg.scenario, **(cfg.overrides | duration), **kwargs)
    if not has_recorded(cfg.scenario):
        raise RunError(f"--track {track}: the run's scenario {cfg.scenario} is generated, it "
                       "has no recorded tracks to drive (drop --track)")  # fmt: skip
    ref, track_id = _resolve_track(cfg.scenario, track)
    return GridSimEnv(ref, ego={"track": track_id}, **duration,
                      **goal_overrides(cfg.goal_seconds), **kwargs)  # fmt: skip


def trained_tracks(config) -> set[str]:
    """The tracks a run of ``config`` trained on, as ``SCENE/ID`` names (as datasets label
    their windows), whether the run named them so or by id alone (of every scene it has); a
    run that named none drew its egos from every track of its recorded scenes that can be
    the ego (or from the scene's own ``ego.track``)."""
    from gridsim.scenario.families.recorded import ego_candidates, ego_track_ids, scene_of
    from gridsim.traffic.track import ids_in_scene

    out = set()
    for _, sc in _recorded(_scenes(config.scenario)):
        scene = scene_of(sc)
        if config.ego_tracks:
            ids = ids_in_scene(list(config.ego_tracks), scene)[0]
        else:
            ids = ego_track_ids(sc, scene)
            if ids == "random":
                ids = [t.track_id for t in ego_candidates(sc)]
            elif isinstance(ids, str):
                ids = [ids]
        out |= {track_name(scene, t) for t in ids}
    return out


def paired_l1(rows: list[dict], others: list[dict]) -> dict:
    """l1 of two planners driven on the same episodes (``rows``, ``others``: one summary per
    episode, in the same order), compared on the episodes that both complete: an episode
    that ends early sums l1 only until it ends, so a planner that fails later would seem to
    do worse; failures are counted by ``completed`` instead. ``episodes``: how many both
    complete; ``l1`` and ``other_l1``: their mean episode l1 [m^2] there; ``l1_change``: the
    relative change from the other's (negative: better; None without such episodes);
    ``better``: on how many of them ``rows``' l1 is lower."""
    both = [(a["l1"], b["l1"]) for a, b in zip(rows, others, strict=True)
            if a["completed"] == 1 and b["completed"] == 1]  # fmt: skip
    if not both:
        return {"episodes": 0, "l1": None, "other_l1": None, "l1_change": None, "better": 0}
    mine, theirs = (sum(v) / len(both) for v in zip(*both, strict=True))
    change = mine / theirs - 1.0 if theirs > 0 else None
    return {"episodes": len(both), "l1": mine, "other_l1": theirs, "l1_change": change,
            "better": sum(a < b for a, b in both)}  # fmt: skip


def heldout_problem(config) -> str | None:
    """Why a run of ``config`` (a :class:`~neurotrajectory.evolve.runs.TrainConfig`) has no held-out
    episodes (a recorded scene all of whose usable tracks it trains on), or None."""
    if not config.ego_tracks:
        return None
    try:
        _other_tracks(config.scenario, config.ego_tracks)
    except RunError as exc:
        return str(exc)
    return None


def _other_tracks(
    scenario: str, trained: tuple[str, ...], scenes: list[tuple[str, Scenario]] | None = None
) -> list[tuple[str, str]]:
    """``(scenario file, track id)`` of every track of ``scenario``'s recorded scenes (one, or
    each of a collection's usable files; ``scenes`` if loaded already, :func:`_scenes`) that
    can be the ego and is not in ``trained`` (ids, or ``SCENE/ID`` names)."""
    from gridsim.scenario.families.recorded import ego_candidates, scene_of
    from gridsim.traffic.track import ids_in_scene

    others = []
    for ref, sc in _recorded(_scenes(scenario) if scenes is None else scenes):
        seen = set(ids_in_scene(list(trained), scene_of(sc))[0])
        need = sc.config.env.horizon_time
        others += [(ref, t.track_id) for t in ego_candidates(sc)
                   if t.track_id not in seen and t.duration >= need]  # fmt: skip
    if not others:
        raise RunError(f"{scenario}: every track of the scene that can be the ego was trained "
                       "on, none is held out; evaluate the run on another scene with "
                       "`neurotrajectory evaluate --group NAME=FOLDER`")  # fmt: skip
    return others
