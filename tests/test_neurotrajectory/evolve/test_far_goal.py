"""A goal beyond the horizon (``env.goal_seconds``): the destination every planner is given lies
further ahead than the last set-point, so that none is handed a set-point for free."""

import json
import math

import numpy as np
import pytest

from gridsim.envs.gridsim_env import GridSimEnv
from gridsim.errors import GridSimError
from gridsim.vehicle.kinematics import BicycleParams
from neurotrajectory.cli import main
from neurotrajectory.compare.baselines.destination_curve import DestinationCurve
from neurotrajectory.compare.baselines.dwa import DWA
from neurotrajectory.compare.predictors import Setting, observation_batch
from neurotrajectory.curves import CurveLimits, curve_to
from neurotrajectory.data.storage import load_dataset
from neurotrajectory.evolve.fitness import scenario_net_config
from neurotrajectory.evolve.runs import Run, RunError, TrainConfig
from neurotrajectory.model import PRESETS, NetConfig

TIMES = 0.5 * np.arange(1, 6)
LIMITS = CurveLimits(a_max=2.0, b_max=6.0, v_max=30.0, max_curvature=math.tan(0.6) / 2.7)


def _drive(goal, steps=15, seed=3):
    env = GridSimEnv("seamless", **({"env": {"goal_seconds": goal}} if goal else {}))
    obs, info = env.reset(seed=seed)
    rows = []
    for _ in range(steps):
        obs, fitness, *_, info = env.step(info["reference_setpoints"])
        rows.append((obs["destination"].copy(), info["reference_setpoints"].copy(), fitness))
    return env, rows


def test_the_destination_is_the_reference_that_far_ahead_and_nothing_else_changes():
    env, far = _drive(5.0)
    _, near = _drive(None)
    t = env.world.time
    ahead = env.reference_in_grid(np.array([t + 5.0]))[0]  # float64; the observation float32
    np.testing.assert_allclose(far[-1][0], ahead, atol=1e-5)
    for (dest_far, ref_far, fit_far), (dest_near, ref_near, fit_near) in zip(
        far, near, strict=True
    ):
        assert np.array_equal(ref_far, ref_near) and np.array_equal(fit_far, fit_near)
        assert np.array_equal(dest_near, ref_near[-1])  # the default: the last set-point
        assert np.hypot(*dest_far) > np.hypot(*dest_near) + 5  # further along the road


def test_a_goal_before_the_last_set_point_is_refused():
    with pytest.raises(
        GridSimError, match=r"env.goal_seconds \(2\) must be >= the horizon's 2.5 s"
    ):
        GridSimEnv("seamless", env={"goal_seconds": 2.0})


def test_the_destination_curve_arrives_at_a_far_goal_at_its_time():
    # 10 m/s straight at a goal 50 m ahead to be reached in 5 s: constant velocity
    out = curve_to(10.0, 1.0, 0.0, (50.0, 0.0), TIMES, LIMITS, arrive=5.0)
    np.testing.assert_allclose(out, np.stack([10 * TIMES, 0 * TIMES], 1), atol=1e-5)
    # arriving at the last set-point's time is the default
    same = curve_to(10.0, 1.0, 0.0, (30.0, 4.0), TIMES, LIMITS, arrive=2.5)
    assert np.array_equal(same, curve_to(10.0, 1.0, 0.0, (30.0, 4.0), TIMES, LIMITS))


def test_the_baselines_aim_at_the_far_goal_on_the_way():
    env, _ = _drive(5.0, steps=20)
    obs = env._observation()
    setting = Setting.from_env(env)
    assert setting.goal_time == 5.0 and setting.far_goal
    batch = observation_batch(obs, env)
    plan = DestinationCurve(setting).predict(batch)[0]
    human = env.reference_in_grid(env.world.time + TIMES)
    assert np.hypot(*(plan[-1] - human[-1])) < 2.0  # close to the human, not at the goal
    assert np.hypot(*(plan[-1] - obs["destination"])) > 10.0
    # DWA aims at the share of the straight way its horizon covers
    params = BicycleParams(v_max=15.0, a_max=2.0, b_max=6.0, delta_max=0.6, v_delta_max=0.8)
    far = Setting(TIMES, 0.25, "north_up", params, goal_time=5.0)
    batch.destination[:] = (40.0, 10.0)
    np.testing.assert_allclose(DWA(far)._goal(batch), [[20.0, 5.0]])
    np.testing.assert_allclose(DWA(Setting(TIMES, 0.25, "north_up", params))._goal(batch),
                               [[40.0, 10.0]])  # fmt: skip


def test_the_network_config_carries_the_goal_and_old_configs_read_the_same():
    cfg = scenario_net_config("seamless", {"env": {"goal_seconds": 5.0}}, PRESETS["tiny"])
    assert cfg.goal_seconds == 5.0 and NetConfig.from_dict(cfg.to_dict()) == cfg
    plain = scenario_net_config("seamless", {}, PRESETS["tiny"])
    assert "goal_seconds" not in plain.to_dict()  # as saved before the setting existed
    assert NetConfig.from_dict(plain.to_dict()) == plain


@pytest.fixture(scope="module")
def far_data(tmp_path_factory):
    root = tmp_path_factory.mktemp("far")
    args = ["record", "--scenario", "seamless", "--episodes", "2", "--episode-seconds", "6",
            "--goal-seconds", "5", "--quiet"]  # fmt: skip
    assert main([*args, "--out", str(root / "seamless")]) == 0
    return root


def test_recorded_windows_see_the_far_goal_and_say_so(far_data):
    ds = load_dataset(far_data / "seamless")
    assert ds.manifest["goal_seconds"] == 5.0
    assert all(m["goal_seconds"] == 5.0 for m in ds.manifest["scenarios"])
    w = ds.windows
    # the destination lies beyond the last set-point the human reached
    assert np.all(np.hypot(*w.destination.T) > np.hypot(*w.target[:, -1].T))


def test_runs_train_and_evaluate_in_one_setting_only(far_data, tmp_path, capsys):
    tiny = ["--preset", "tiny", "--population", "4", "--generations", "1", "--episodes", "1",
            "--episode-seconds", "3", "--quiet", "--heldout", "1"]  # fmt: skip
    # data recorded for the far goal cannot warm-start a run of the default setting
    bad = tmp_path / "bad"
    assert main(["train", *tiny, "--pretrain", str(far_data / "seamless"), "--out", str(bad)]) == 2
    assert "its windows see the destination 5 s ahead, the run's network at the last " \
        "set-point" in capsys.readouterr().err  # fmt: skip
    assert not bad.exists()
    run = tmp_path / "run"
    assert main(["train", *tiny, "--goal-seconds", "5", "--pretrain", str(far_data / "seamless"),
                 "--out", str(run)]) == 0  # fmt: skip
    capsys.readouterr()
    assert Run.open(run).config.goal_seconds == 5.0
    from neurotrajectory.compare.front import load_front

    assert all(net.cfg.goal_seconds == 5.0 for net in load_front(run)[3])  # the prior's goal
    assert json.loads((run / "heldout.json").read_text())["warm_start"]["episodes"] == 1
    # evaluated in the other setting: refused before anything is written
    out = tmp_path / "eval"
    assert main(["evaluate", "--run", str(run), "--groups", "seamless", "--out", str(out),
                 "--quiet"]) == 2  # fmt: skip
    assert "was trained with the destination 5 s ahead; give --goal-seconds 5 to evaluate " \
        "it in its setting" in capsys.readouterr().err  # fmt: skip
    assert not out.exists()
    with pytest.raises(RunError, match="goal_seconds must be a finite number > 0"):
        TrainConfig(goal_seconds=float("nan"))
    with pytest.raises(SystemExit):  # argparse's usage error
        main(["train", "--goal-seconds", "-1", "--out", str(tmp_path / "x")])
    assert "--goal-seconds: must be a finite number of seconds > 0, got -1" in (
        capsys.readouterr().err
    )
