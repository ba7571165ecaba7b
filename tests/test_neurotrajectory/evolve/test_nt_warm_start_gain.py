"""What evolution buys over its warm start: the warm start kept, validated and driven beside
the knee; the learning curve; anchored selection (the warm start in every generation, its l1
a constraint)."""

import json
from pathlib import Path

import numpy as np
import pytest
from golden import run_history, untimed_history

from neurotrajectory.cli import main
from neurotrajectory.evolve.backends import WorkerSpec, make_backend
from neurotrajectory.evolve.evolution import (
    ANCHOR,
    GAConfig,
    anchored_violation,
    initial_recipes,
    next_generation,
)
from neurotrajectory.evolve.fitness import Evaluator
from neurotrajectory.evolve.genome import Recipe
from neurotrajectory.evolve.pareto import knee_distance, minimised
from neurotrajectory.evolve.runs import Run, RunError, TrainConfig

#: Training runs, rollouts or subprocesses: left out of the quick loop (`pytest -m "not slow"`).
pytestmark = pytest.mark.slow

WARM = dict(preset="tiny", population=5, generations=3, episodes=1, episode_seconds=3.0, seed=2,
            pretrain_episodes=2, pretrain_epochs=1, validation_episodes=2, batch=3)  # fmt: skip


#: A tiny training command line (plus --heldout and --out).
TINY_CLI = ["--preset", "tiny", "--population", "3", "--generations", "1", "--episodes", "1",
            "--episode-seconds", "2", "--validation-episodes", "1", "--quiet"]  # fmt: skip


@pytest.fixture(scope="module")
def anchored_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("anchored") / "run"
    Run.create(out, TrainConfig(selection="anchored", **WARM)).train(progress=False)
    return out


def _evaluator(run: Run) -> Evaluator:
    cfg = run.config
    return Evaluator(cfg.scenario, cfg.overrides, run.net_config, list(cfg.validation_seeds))


def test_the_anchor_is_the_warm_start_in_every_generation(anchored_run):
    run = Run.open(anchored_run)
    warm = run.warm_start_genome()
    gen, population, fitness, _ = run.load_checkpoint()
    assert gen == 2 and np.array_equal(population[ANCHOR], warm)
    # its fitness in each generation is the warm start's on that generation's episodes
    ev = _evaluator(run)
    for h in run_history(anchored_run):
        f, _ = ev.evaluate(warm, run.config.episode_seeds(h["generation"]))
        assert h["fitness"][ANCHOR] == f.tolist()


def test_the_learning_curve_is_the_knee_and_the_warm_start_on_the_validation_episodes(
    anchored_run,
):
    run = Run.open(anchored_run)
    hist = run_history(anchored_run)
    assert all("knee_validation" in h for h in hist)
    assert "warm_start_validation" in hist[0] and "warm_start_validation" not in hist[1]
    ev = _evaluator(run)
    f, s = ev.evaluate(run.warm_start_genome())
    assert hist[0]["warm_start_validation"] == {"index": ANCHOR, "l1": f[0], "l2": f[1],
                                                "l3": f[2], "violation": s.lost}  # fmt: skip
    # the last generation's knee: picked from its first front, scored on the validation seeds
    _, population, fitness, _ = run.load_checkpoint()
    last = hist[-1]
    front = np.flatnonzero(np.array(last["rank"]) == 0)
    knee = int(front[np.argmin(knee_distance(minimised(fitness[front])))])
    assert last["knee_validation"]["index"] == knee
    f, _ = ev.evaluate(population[knee])
    assert [last["knee_validation"][k] for k in ("l1", "l2", "l3")] == f.tolist()
    assert (anchored_run / "plots" / "learning_curve.png").stat().st_size > 5000
    warm = json.loads((anchored_run / "front.json").read_text())["warm_start"]
    assert warm == hist[0]["warm_start_validation"]
    # its index names the candidate that is the warm start: individual 0, kept every generation
    assert np.array_equal(population[warm["index"]], run.warm_start_genome())


def test_the_anchored_front_is_no_worse_than_the_warm_start_on_validation_l1(anchored_run):
    summary = json.loads((anchored_run / "front.json").read_text())
    warm = summary["warm_start"]
    assert warm["violation"] == 0  # tiny episodes: the warm start completes them
    for member in summary["front"]:
        assert member["violation"] == 0 and member["l1"] <= warm["l1"]


def test_the_best_validated_knee_is_kept_as_a_final_candidate(anchored_run):
    run = Run.open(anchored_run)
    scores = [h["knee_validation"] for h in run_history(anchored_run)]
    best_gen = min(range(len(scores)), key=lambda g: (scores[g]["violation"], scores[g]["l1"]))
    with np.load(anchored_run / "best_knee.npz") as best:
        assert int(best["generation"]) == best_gen
        genome = best["genome"]
    f, _ = _evaluator(run).evaluate(genome)
    assert f.tolist() == [scores[best_gen][k] for k in ("l1", "l2", "l3")]
    summary = json.loads((anchored_run / "front.json").read_text())
    _, population, _, _ = run.load_checkpoint()
    if any(np.array_equal(genome, g) for g in population):
        assert "best_knee" not in summary  # the last population holds it
    else:
        assert summary["best_knee"] == {"generation": best_gen, "index": len(population)}
    # the front's members: the candidates' own genomes
    with np.load(anchored_run / "front.npz") as front:
        for i, g in zip(front["indices"], front["genomes"], strict=True):
            assert np.array_equal(g, population[i] if i < len(population) else genome)


def test_an_anchored_run_resumes_to_the_same_result(anchored_run, tmp_path):
    out = tmp_path / "run"
    Run.create(out, TrainConfig(selection="anchored", **WARM)).train(progress=False, stop_after=1)
    Run.open(out).train(progress=False)

    assert untimed_history(out) == untimed_history(anchored_run)
    with np.load(anchored_run / "front.npz") as a, np.load(out / "front.npz") as b:
        assert np.array_equal(a["genomes"], b["genomes"])


def test_anchored_violation_orders_lost_time_then_l1_worse_than_the_anchor():
    fitness = np.array([[100.0, 1, 5], [90, 9, 1], [150, 0, 9], [400, 0, 9], [80, 0, 9]])
    lost = np.array([0, 0, 0, 0, 0.1])
    v = anchored_violation(fitness, lost)
    assert v[0] == v[1] == 0  # the anchor, and a member closer to the human
    assert 0 < v[2] < v[3] < 1 < v[4]  # worse l1 by 50 %, by 300 %; lost 10 % of its time
    assert v[4] == pytest.approx(1.1)


def test_anchored_generations_carry_the_anchor_and_the_elites_nearest_the_knee():
    # 6 members; the anchor 0 and 1-4 feasible; 5 worse on l1
    fitness = np.array([[100.0, 5, 50], [60, 9, 40], [99, 1, 50], [70, 4, 49], [95, 8, 60],
                        [300, 0, 99]])  # fmt: skip
    v = anchored_violation(fitness, np.zeros(6))
    cfg = GAConfig(population=6, elite_fraction=0.5)  # 3 elites: the anchor and 2
    recipes, rank = next_generation(fitness, cfg, 0, 0, 10, 1000, v, anchored=True)
    assert recipes[0] == Recipe(parent=ANCHOR)
    front = [i for i in range(6) if rank[i] == 0]
    assert 5 not in front
    others = [i for i in front if i != ANCHOR]
    nearest = np.array(others)[np.argsort(knee_distance(minimised(fitness[others])))]
    assert [r.parent for r in recipes[1:3]] == nearest[:2].tolist()
    assert all(r.sigma > 0 or r.other is not None for r in recipes[3:])  # children, not copies


@pytest.mark.parametrize("backend", ["local", "processes"])
def test_evaluate_members_equals_the_population_s_evaluation(backend):
    cfg = TrainConfig(**{**WARM, "pretrain_episodes": 0})
    spec = WorkerSpec(cfg.scenario, cfg.overrides, cfg.net, cfg.episode_seeds(0), batch=2)
    b = make_backend(backend, spec, workers=2)
    try:
        b.advance(initial_recipes(cfg.ga, cfg.seed))
        seeds = cfg.episode_seeds(0)
        full, full_stats = b.evaluate(cfg.population, seeds)
        some, some_stats = b.evaluate_members([3, 0, 4], seeds)
        assert np.array_equal(some, full[[3, 0, 4]])
        assert [s["lost"] for s in some_stats] == [full_stats[i]["lost"] for i in (3, 0, 4)]
    finally:
        b.close()


def test_heldout_drives_the_warm_start_beside_the_knee(anchored_run, tmp_path, capsys):
    report = tmp_path / "heldout.json"
    assert main(["heldout", "--run", str(anchored_run), "--episodes", "2",
                 "--out", str(report)]) == 0  # fmt: skip
    r = json.loads(report.read_text())
    assert set(r["warm_start"]) == set(r["network"])
    assert len(r["warm_start_episodes"]) == 2
    assert [e["seed"] for e in r["warm_start_episodes"]] == r["seeds"]
    printed = capsys.readouterr().out
    assert "its warm start" in printed and "destination curve" in printed
    # the same numbers as driving the warm start with the run's plan smoothing
    from neurotrajectory.compare.closed_loop import drive_episodes, summarise
    from neurotrajectory.compare.front import load_warm_start

    run = Run.open(anchored_run)
    policy = load_warm_start(run)
    assert policy.keep == run.config.plan_smoothing
    rows = drive_episodes(run.config.scenario, policy, r["seeds"], r["episode_seconds"])
    assert summarise(rows) == r["warm_start"]
    # the pair compared on the episodes both complete, from the same episode rows
    pairs = zip(r["episodes"], r["warm_start_episodes"], strict=True)
    both = [(a["l1"], b["l1"]) for a, b in pairs if a["completed"] == 1 and b["completed"] == 1]
    assert r["paired"]["episodes"] == len(both)
    if both:
        assert r["paired"]["l1"] == np.mean([a for a, _ in both])
        assert "both the knee member and its warm start complete" in printed


def test_paired_l1_compares_only_the_episodes_both_complete():
    from neurotrajectory.compare.front import paired_l1

    rows = [{"l1": 10.0, "completed": 1.0}, {"l1": 900.0, "completed": 0.0},
            {"l1": 4.0, "completed": 1.0}, {"l1": 7.0, "completed": 1.0}]  # fmt: skip
    others = [{"l1": 12.0, "completed": 1.0}, {"l1": 300.0, "completed": 0.0},
              {"l1": 5.0, "completed": 0.0}, {"l1": 6.0, "completed": 1.0}]  # fmt: skip
    # episode 1 failed for both (the later failure summed more l1), episode 2 for one
    assert paired_l1(rows, others) == {"episodes": 2, "l1": 8.5, "other_l1": 9.0,
                                       "l1_change": 8.5 / 9.0 - 1, "better": 1}  # fmt: skip
    assert paired_l1(rows[1:2], others[1:2])["episodes"] == 0
    with pytest.raises(ValueError):
        paired_l1(rows, others[:2])  # not the same episodes


def test_a_run_without_a_warm_start_has_no_warm_start_entry(tmp_path):
    out = tmp_path / "run"
    args = [*TINY_CLI, "--heldout", "1"]
    assert main(["train", *args, "--out", str(out)]) == 0
    assert not {"warm_start", "paired"} & set(json.loads((out / "heldout.json").read_text()))
    assert "warm_start" not in json.loads((out / "front.json").read_text())
    assert "warm_start_validation" not in run_history(out)[0]
    assert "knee_validation" in run_history(out)[0]
    assert not (out / "warm_start.npz").exists()


def test_anchored_selection_needs_a_warm_start_and_old_runs_read_as_pareto(tmp_path, capsys):
    with pytest.raises(RunError, match="--selection anchored starts from the warm start"):
        TrainConfig(selection="anchored")
    with pytest.raises(RunError, match="unknown selection 'best'; choose from"):
        TrainConfig(selection="best")
    assert main(["train", "--selection", "anchored", "--out", str(tmp_path / "x")]) == 2
    assert "give --pretrain or --pretrain-episodes" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
    run = Run.create(tmp_path / "run", TrainConfig(preset="tiny"))
    stored = json.loads((run.out / "config.json").read_text())
    del stored["train"]["selection"]  # a run saved before the field
    (run.out / "config.json").write_text(json.dumps(stored))
    assert Run.open(run.out).config.selection == "pareto"


def test_a_damaged_warm_start_file_is_named(anchored_run, tmp_path):
    import shutil

    run = Path(shutil.copytree(anchored_run, tmp_path / "copy"))
    (run / "warm_start.npz").write_bytes(b"not a zip")
    with pytest.raises(RunError, match=r"warm_start.npz: not a readable .npz archive of a run"):
        Run.open(run).warm_start_genome()


def test_the_command_line_anchors_a_warm_started_run_by_default(tmp_path):
    tiny = [*TINY_CLI, "--heldout", "0"]
    assert main(["train", *tiny, "--out", str(tmp_path / "plain")]) == 0
    assert Run.open(tmp_path / "plain").config.selection == "pareto"
    warm = ["--pretrain-episodes", "2", "--pretrain-epochs", "1"]
    assert main(["train", *tiny, *warm, "--out", str(tmp_path / "warm")]) == 0
    assert Run.open(tmp_path / "warm").config.selection == "anchored"
    assert main(["train", *tiny, *warm, "--selection", "pareto",
                 "--out", str(tmp_path / "asked")]) == 0  # fmt: skip
    assert Run.open(tmp_path / "asked").config.selection == "pareto"
