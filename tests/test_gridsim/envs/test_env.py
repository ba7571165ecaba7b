"""GridSim-v0: registration, gymnasium conformance, determinism, episodes, vector envs."""

import hashlib
import multiprocessing as mp
import subprocess
import sys
import tomllib
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from paths import ROOT

import gridsim
from gridsim.envs import ENV_ID, register_envs
from gridsim.envs.gridsim_env import EGO_FEATURES, GridSimEnv, step_all
from gridsim.envs.vector import mo_async_worker
from gridsim.envs.wrappers import LinearScalarization
from gridsim.errors import ScenarioError
from gridsim.policies import LaneFollow
from gridsim.scenario.loader import builtin_scenarios

SHORT = {"simulation": {"duration": 4.0}}


def make(scenario="seamless", **kw):
    return gym.make(ENV_ID, scenario=scenario, **{**SHORT, **kw})


def test_registration_is_idempotent_and_quiet(capsys):
    register_envs()
    register_envs()
    assert ENV_ID in gym.registry and gridsim.ENV_ID == ENV_ID
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        env = gym.make(ENV_ID)
        env.reset(seed=0)
        env.step(env.action_space.sample())
    assert [str(w.message) for w in caught] == []
    assert capsys.readouterr() == ("", "")


@pytest.mark.slow
def test_make_by_module_path_in_a_fresh_interpreter(tmp_path):
    """As a user's script: from a folder of its own (not the checkout, whose gridsim/ would be
    imported instead of the installed one), nothing printed but the result."""
    code = (
        "import gymnasium as gym; e = gym.make('gridsim:GridSim-v0');"
        "print(e.reset(seed=1)[0]['grids'].shape)"
    )
    out = subprocess.run(
        [sys.executable, "-W", "error", "-c", code], capture_output=True, text=True, cwd=tmp_path
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "(5, 128, 128)" and out.stderr == ""


@pytest.mark.parametrize("action_type", ["trajectory", "control", "discrete"])
@pytest.mark.parametrize("scenario", sorted(builtin_scenarios()))
def test_check_env_passes(scenario, action_type):
    env = gym.make(
        ENV_ID, scenario=scenario, action_type=action_type, render_mode="rgb_array", **SHORT
    )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=False)
    # The only remarks allowed: the reward is a vector (MO-Gymnasium convention) and the
    # physical (non-normalised) action bounds.
    allowed = ("The reward returned by `step()` must be a float", "symmetric and normalized space")
    unexpected = [str(w.message) for w in caught if not any(a in str(w.message) for a in allowed)]
    assert unexpected == []


def test_spaces_and_documented_observation():
    env = make()
    obs, info = env.reset(seed=3)
    u = env.unwrapped
    assert set(obs) == {"grids", "ego", "destination"}
    assert obs["grids"].shape == (5, 128, 128) and obs["grids"].dtype == np.uint8
    assert set(np.unique(obs["grids"])) <= {0, 128, 255}
    assert obs["ego"].shape == (len(EGO_FEATURES),) and obs["ego"].dtype == np.float32
    assert obs["ego"][0] == pytest.approx(u.world.ego[3])  # speed
    assert np.hypot(*obs["ego"][4:6]) == pytest.approx(1.0)  # cos, sin of heading
    assert env.action_space.shape == (5, 2)
    assert u.reward_space.shape == (3,)
    # The destination is the reference position at the end of the horizon.
    np.testing.assert_allclose(obs["destination"], info["reference_setpoints"][-1], atol=1e-5)
    assert info["reference_setpoints"].shape == (5, 2)


def test_reference_in_grid_is_the_reference_at_any_time_of_the_look_ahead():
    env = make()
    with pytest.raises(RuntimeError, match="call reset"):
        env.unwrapped.reference_in_grid([0.0])
    obs, info = env.reset(seed=3)
    for _ in range(7):
        obs, _, _, _, info = env.step(info["reference_setpoints"])
    u = env.unwrapped
    times = info["time"] + 0.5 * np.arange(1, 6)
    got = u.reference_in_grid(times)
    np.testing.assert_array_equal(got.astype(np.float32), info["reference_setpoints"])
    now = u.reference_in_grid([info["time"]])[0]  # the human now, seen from the ego
    assert np.hypot(*now) < 1.0  # following the human's set-points keeps the ego near it


def rollout_digest(scenario, seed, steps, action_type="trajectory"):
    env = GridSimEnv(scenario, action_type=action_type, **SHORT)
    env.action_space.seed(seed)
    h = hashlib.sha256()
    obs, info = env.reset(seed=seed)
    for _ in range(steps):
        obs, r, term, trunc, info = env.step(env.action_space.sample())
        for v in (
            obs["grids"],
            obs["ego"],
            obs["destination"],
            r,
            info["pose"],
            info["reference_setpoints"],
        ):
            h.update(np.ascontiguousarray(v).tobytes())
        h.update(repr((term, trunc, info["collision"], info["off_road"])).encode())
        if term or trunc:
            obs, info = env.reset()
    return h.hexdigest()


@pytest.mark.parametrize("scenario", ["seamless", "inner_city", "us101_3_3"])
def test_same_seed_same_episode_bit_for_bit(scenario):
    a = rollout_digest(scenario, 7, 40, "control")
    assert a == rollout_digest(scenario, 7, 40, "control")
    assert a != rollout_digest(scenario, 8, 40, "control")


def _digest_in_child(queue):
    queue.put(rollout_digest("seamless", 11, 30))


@pytest.mark.slow
def test_same_seed_same_episode_in_a_spawned_process():
    ctx = mp.get_context("spawn")
    q = ctx.Queue()
    p = ctx.Process(target=_digest_in_child, args=(q,))
    p.start()
    child = q.get(timeout=120)
    p.join(timeout=60)
    assert child == rollout_digest("seamless", 11, 30)


def run_episode(env, policy, seed):
    obs, info = env.reset(seed=seed)
    total = np.zeros(3)
    while True:
        obs, r, term, trunc, info = env.step(policy(env, obs, info))
        total += r
        if term or trunc:
            return total, term, trunc, info


def test_reference_policy_completes_a_seamless_episode_with_zero_l1():
    env = gym.make(ENV_ID)  # full 60 s episode
    total, term, trunc, info = run_episode(env, lambda e, o, i: i["reference_setpoints"], seed=0)
    assert trunc and not term
    assert info["time"] == 60.0  # the clock as a user compares it (the sum of ticks drifts)
    assert not info["collision"] and not info["off_road"]
    assert total[0] < 1e-6
    assert total[2] > 0
    # The ego did drive the reference: within 2 m of it at the end.
    u = env.unwrapped
    ref_now = u.reference.positions(np.array([u.world.time]))[0]
    assert np.hypot(*(u.world.ego[:2] - ref_now)) < 2.0


def test_an_episode_may_drive_on_past_its_destination_to_its_time_limit():
    """``env.end_at_destination: false`` (as ``record`` drives recorded tracks): a human who
    crawls within the destination's tolerance of its end point for seconds (US-101 track
    422) no longer ends the episode there; info still says the destination is reached, and
    the steps before are the same."""

    def drive(**env_options):
        env = GridSimEnv("us101_4_1", ego={"track": "422"}, **env_options)
        obs, info = env.reset(seed=0)
        steps = []
        while True:
            obs, terms, terminated, truncated, info = env.step(info["reference_setpoints"])
            steps.append((env.world.ego.copy(), terms, info["destination_reached"]))
            if terminated or truncated:
                return steps, terminated, truncated

    ended, terminated, _ = drive()
    assert terminated and ended[-1][2]
    on, terminated, truncated = drive(env={"end_at_destination": False})
    assert truncated and not terminated and len(on) > len(ended) + 20
    assert all(reached for *_, reached in on[len(ended) - 1 :])
    for (ego_a, terms_a, _), (ego_b, terms_b, _) in zip(ended, on, strict=False):
        assert np.array_equal(ego_a, ego_b) and np.array_equal(terms_a, terms_b)
    # the episode loop says it ended at its time limit (it said "destination reached")
    from gridsim.envs.episode import run_episode as loop
    from gridsim.policies import Reference

    env = GridSimEnv("us101_4_1", ego={"track": "422"}, env={"end_at_destination": False})
    assert loop(env, Reference(), seed=0).ended_by == "time limit"
    assert loop(GridSimEnv("us101_4_1", ego={"track": "422"}), Reference(),
                seed=0).ended_by == "destination reached"  # fmt: skip


def test_lane_following_completes_and_steering_off_is_terminated():
    env = GridSimEnv("seamless", action_type="control")
    total, term, trunc, info = run_episode(env, LaneFollow(), seed=1)
    assert not info["collision"] and not info["off_road"]
    assert trunc or info["destination_reached"]  # faster than the human: done early
    assert total[0] > 0  # it does not follow the human reference exactly
    steer_off = lambda e, o, i: np.array([1.0, 0.3 if e.unwrapped.world.time < 1.0 else 0.0])  # noqa: E731
    total, term, trunc, info = run_episode(env, steer_off, seed=1)
    assert term and info["off_road"] and not trunc


def test_fitness_terms_follow_their_definitions():
    env = GridSimEnv("seamless", action_type="control", **SHORT)
    obs, info = env.reset(seed=2)
    u = env.unwrapped
    rate = 0.05
    obs, r, term, trunc, info = env.step(np.array([0.5, rate], np.float32))
    assert r.dtype == np.float32 and r.shape == (3,)
    assert r[1] == pytest.approx(rate, rel=1e-5)  # one tick per decision at the defaults
    v = u.world.ego[3]
    lo, hi = u.cfg.speed_range
    assert r[2] == pytest.approx(v if lo <= v <= hi else 0.0, rel=1e-5)
    assert info["l1"] == pytest.approx(float(r[0]))
    # Commanding the reference as a plan scores l1 = 0; an offset plan scores its square.
    env2 = GridSimEnv("seamless", **SHORT)
    obs, info = env2.reset(seed=2)
    _, r, *_ = env2.step(info["reference_setpoints"] + np.array([0.0, 1.0], np.float32))
    assert r[0] == pytest.approx(5 * 1.0, rel=1e-4)


def test_bad_actions_and_arguments_raise_clear_errors():
    env = make()
    env.reset(seed=0)
    bad = np.zeros((5, 2), np.float32)
    bad[2, 1] = np.nan
    with pytest.raises(ValueError, match="NaN or infinite"):
        env.step(bad)
    with pytest.raises(ValueError, match=r"shape \(5, 2\)"):
        env.step(np.zeros(3, np.float32))
    huge = np.full((5, 2), 1e6, np.float32)  # clipped to the space, not an error
    env.step(huge)
    with pytest.raises(ValueError, match="action_type must be one of"):
        GridSimEnv(action_type="steer")
    with pytest.raises(ScenarioError, match="traffic.participant: unknown key"):
        gym.make(ENV_ID, traffic={"participant": 3})
    with pytest.raises(ValueError, match="discrete action must be an integer"):
        d = GridSimEnv(action_type="discrete", **SHORT)
        d.reset(seed=0)
        d.step(7)
    with pytest.raises(RuntimeError, match="reset"):
        GridSimEnv(**SHORT).step(np.zeros((5, 2)))


def test_scalarised_wrapper():
    env = LinearScalarization(make(), weights=(-1.0, -2.0, 0.5))
    obs, info = env.reset(seed=0)
    obs, r, term, trunc, info = env.step(info["reference_setpoints"])
    assert isinstance(r, float)
    assert r == pytest.approx(float(np.dot([-1.0, -2.0, 0.5], info["fitness"])), rel=1e-5)
    with pytest.raises(ValueError, match="3 finite numbers"):
        LinearScalarization(make(), weights=(1.0, 2.0))
    # its reward space is the scalar's (libraries count objectives by it: it said 3)
    assert env.get_wrapper_attr("reward_space").shape == ()
    assert env.get_wrapper_attr("reward_space").contains(np.float64(r))
    scalar = gym.make("GridSimScalar-v0")
    assert scalar.get_wrapper_attr("reward_space").shape == ()
    assert scalar.unwrapped.reward_space.shape == (3,)  # (GridSim-v0's own, under it)
    only_l3 = LinearScalarization(make(), weights=(0.0, 0.0, 1.0)).reward_space
    assert only_l3.low == 0 and only_l3.high == np.inf
    # vector envs of it stack the scalars, in-process and in subprocesses alike (the
    # in-process one copied each scalar into three columns of GridSim-v0's shape)
    from gridsim.envs.vector import MOAsyncVectorEnv, MOSyncVectorEnv

    fns = [lambda: LinearScalarization(make(action_type="control")) for _ in range(2)]
    stacked = []
    for cls in (MOSyncVectorEnv, MOAsyncVectorEnv):
        venv = cls(fns)
        try:
            venv.reset(seed=0)
            rewards = venv.step(np.zeros((2, 2), np.float32))[1]
            assert venv.reward_space.shape == () and rewards.shape == (2,)
            stacked.append(rewards)
        finally:
            venv.close()
    np.testing.assert_array_equal(*stacked)


def test_maximised_objectives_flip_the_minimised_ones():
    """MORL libraries maximise every objective: the wrapper's reward is ``[-l1, -l2, l3]`` of
    the very step (the same episode unwrapped, bit for bit), inside its own reward_space."""
    from gridsim.envs.wrappers import MaximisedObjectives

    plain, flipped = make(), MaximisedObjectives(make())
    plain.reset(seed=3)
    flipped.reset(seed=3)
    rng = np.random.default_rng(0)
    for _ in range(5):
        action = plain.action_space.low + rng.random(plain.action_space.shape) * (
            plain.action_space.high - plain.action_space.low)  # fmt: skip
        r = plain.step(action)[1]
        _, m, _, _, info = flipped.step(action)
        assert m.dtype == np.float32 and np.array_equal(info["fitness"], r)
        assert np.array_equal(m, np.array([-r[0], -r[1], r[2]], np.float32))
        assert flipped.reward_space.contains(m) and r[0] > 0
    assert flipped.reward_space.high[0] == 0 and flipped.reward_space.low[2] == 0
    # over or under the scalarisation, the vector is gone: refused (it gave [s, s, -s])
    for stacked in (lambda: MaximisedObjectives(LinearScalarization(make())),
                    lambda: LinearScalarization(MaximisedObjectives(make()))):  # fmt: skip
        with pytest.raises(ValueError, match=r"takes the fitness vector .* is already under it"):
            stacked()


def test_vector_envs():
    venv = gym.vector.SyncVectorEnv([lambda: LinearScalarization(make()) for _ in range(2)])
    try:
        obs, _ = venv.reset(seed=[1, 2])
        assert obs["grids"].shape == (2, 5, 128, 128)
        for _ in range(45):  # past the 4 s episodes: autoreset
            obs, r, term, trunc, info = venv.step(venv.action_space.sample())
        assert r.shape == (2,)
    finally:
        venv.close()
    venv = gym.vector.AsyncVectorEnv([lambda: make() for _ in range(2)])  # vector rewards
    try:
        obs, _ = venv.reset(seed=[1, 2])
        obs, r, term, trunc, info = venv.step(venv.action_space.sample())
        assert r.shape == (2, 3)
        assert obs["ego"].shape == (2, len(EGO_FEATURES))
    finally:
        venv.close()


#: Run first in a subprocess: the trainer's extra cannot be imported, as if not installed.
_WITHOUT_TRAIN_EXTRA = """
import sys
import tomllib
class NotInstalled:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("torch", "matplotlib", "moocore"):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
sys.meta_path.insert(0, NotInstalled())
"""


@pytest.mark.slow
def test_the_simulator_works_without_the_trainers_extra(tmp_path):
    code = _WITHOUT_TRAIN_EXTRA + (
        "import gymnasium as gym, gridsim\n"
        "from gridsim.video import record_rollout\n"
        "e = gym.make('GridSim-v0', render_mode='rgb_array', simulation={'duration': 1.0})\n"
        "e.reset(seed=0)\n"
        f"record_rollout(e, lambda e, o, i: i['reference_setpoints'], {str(tmp_path / 'a.gif')!r},"
        " steps=5, seed=0)\n"
        "from gridsim.cli import main\n"
        "assert main(['validate', 'seamless']) == 0\n"
        "from neurotrajectory.__main__ import main\n"
        "sys.exit(main(['--help']))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode == 2, out.stderr
    assert (tmp_path / "a.gif").stat().st_size > 0
    message = ("neurotrajectory: error: the trainer needs torch, matplotlib, moocore, which the "
               'simulator alone does not install: pip install "gridsim[train]"')  # fmt: skip
    assert message in out.stderr
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    base = " ".join(project["dependencies"])
    assert not any(m in base for m in ("torch", "matplotlib", "moocore"))
    assert {d.split("=")[0].split(">")[0] for d in project["optional-dependencies"]["train"]} == {
        "torch", "matplotlib", "moocore"}  # fmt: skip


@pytest.mark.slow
def test_gridsim_never_imports_torch():
    code = (
        "import sys, gymnasium as gym, gridsim; e = gym.make('GridSim-v0'); e.reset(seed=0);"
        "e.step(e.action_space.sample()); print('torch' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


@pytest.mark.parametrize(
    "action_type, action, message",
    [
        ("discrete", np.inf, "discrete action contains NaN or infinite values: inf"),
        ("discrete", -np.inf, "discrete action contains NaN or infinite values: -inf"),
        ("discrete", True, "discrete action must hold real numbers (integers or floats), got "
                           "dtype bool"),
        ("discrete", 2.5, "discrete action must be an integer in [0, 4], got 2.5"),
        ("discrete", "1", "discrete action must hold real numbers"),
        ("control", np.array([1 + 2j, 0]), "control action must hold real numbers (integers or "
                                           "floats), got dtype complex128"),
        ("control", np.array([True, False]), "got dtype bool"),
        ("trajectory", np.zeros((5, 2), complex), "trajectory action must hold real numbers"),
        ("trajectory", [[1.0, 2.0], [3.0]], "trajectory action must be an array of numbers"),
    ],
)  # fmt: skip
def test_actions_of_the_wrong_kind_raise_value_errors_naming_them(action_type, action, message):
    env = GridSimEnv(action_type=action_type, **SHORT)
    env.reset(seed=0)
    with pytest.raises(ValueError) as info:
        env.step(action)
    assert message in str(info.value)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    data=st.data(),
    dtype=st.sampled_from(
        ["float32", "float64", "int8", "int64", "uint8", "bool", "complex64", "float16"]
    ),  # fmt: skip
    shape=st.sampled_from([(), (1,), (2,), (5, 2), (2, 5), (5, 2, 1), (0,)]),
    action_type=st.sampled_from(["trajectory", "control", "discrete"]),
)
def test_actions_of_any_dtype_and_shape_step_or_raise_value_error(data, dtype, shape, action_type):
    env = FUZZ_ENVS.setdefault(action_type, GridSimEnv(action_type=action_type, **SHORT))
    if env.world is None:
        env.reset(seed=0)
    action = data.draw(hnp.arrays(np.dtype(dtype), shape))
    try:
        obs, r, term, trunc, info = env.step(action)
    except ValueError as exc:
        assert f"{action_type} action" in str(exc)
        return
    assert env.observation_space.contains(obs) and np.all(np.isfinite(r))
    if term or trunc:
        env.reset(seed=1)


FUZZ_ENVS: dict = {}


@pytest.mark.parametrize("scenario", [None, 123, 4.5])
def test_a_scenario_that_is_not_a_name_or_path(scenario):
    with pytest.raises(ScenarioError) as info:
        gym.make(ENV_ID, scenario=scenario)
    assert str(info.value) == (
        "scenario must be a built-in name, a YAML or XML path, a folder or glob of them, or a "
        f"Scenario, got {scenario!r} ({type(scenario).__name__})"
    )


def test_a_list_of_scenarios_is_shown_as_the_text_that_names_them():
    said = r"\(list\); several as one text, separated by commas: scenario='us101_4_1,us101_3_3'$"
    with pytest.raises(ScenarioError, match=said):
        gym.make(ENV_ID, scenario=["us101_4_1", "us101_3_3"])


@pytest.mark.parametrize("scenario", ["", "  "])
def test_an_empty_scenario_is_said_to_be_empty(scenario):
    """An empty name was the current folder: ": no scenario files (.yaml, .yml, .xml) in it"."""
    with pytest.raises(ScenarioError, match=r"^scenario is empty: give a built-in name \(inner_"):
        gym.make(ENV_ID, scenario=scenario)


def test_human_rendering_is_refused_with_the_alternatives():
    for make_it in (lambda: gym.make(ENV_ID, render_mode="human"),
                    lambda: GridSimEnv(render_mode="human")):  # fmt: skip
        with pytest.raises(ValueError) as info:
            make_it()
        message = str(info.value)
        assert "got 'human'" in message and "never opens a window" in message
        assert "'rgb_array'" in message and "--video" in message


def test_rgb_array_list_collects_the_frames_through_make():
    """gym.make's "rgb_array_list" (gymnasium's RenderCollection over "rgb_array"): render()
    returns every frame since the last call, the reset's included, each the env's own."""
    env = gym.make(ENV_ID, render_mode="rgb_array_list", **SHORT)
    single = gym.make(ENV_ID, render_mode="rgb_array", **SHORT)
    env.reset(seed=0)
    single.reset(seed=0)
    action = np.zeros(env.action_space.shape, np.float32) + env.action_space.low
    for _ in range(2):
        env.step(action)
        single.step(action)
    frames = env.render()
    assert len(frames) == 3 and env.render() == []
    assert np.array_equal(frames[-1], single.render())


def test_render_says_what_it_needs():
    """render() before reset() is refused like the other calls; without a render mode it
    returns None with gymnasium's warning saying how to get frames (it was silent)."""
    with pytest.raises(RuntimeError, match=r"call reset\(\) before render\(\)"):
        GridSimEnv(render_mode="rgb_array").render()
    env = GridSimEnv(**SHORT)
    env.reset(seed=0)
    with pytest.warns(UserWarning, match='render_mode="rgb_array"'):
        assert env.render() is None


def test_step_after_termination_is_refused_until_reset():
    env = GridSimEnv(action_type="control", **SHORT)
    env.reset(seed=0)
    terminated = False
    for _ in range(40):  # full throttle, full lock: off the road
        *_, terminated, truncated, info = env.step(np.array([2.0, 1.0]))
        if terminated or truncated:
            break
    assert terminated and (info["off_road"] or info["collision"])
    with pytest.raises(RuntimeError, match=r"the episode has terminated .*call reset\(\)"):
        env.step(np.zeros(2))
    env.reset(seed=0)
    env.step(np.zeros(2))


def test_a_step_after_the_time_limit_is_refused_until_reset():
    env = gym.make("GridSim-v0", simulation={"duration": 0.3})
    _, info = env.reset(seed=0)
    truncated = False
    for _ in range(3):
        _, _, terminated, truncated, info = env.step(info["reference_setpoints"])
    assert truncated and not terminated
    with pytest.raises(RuntimeError, match=r"reached its time limit \(0.3 s, simulation.duration"):
        env.step(info["reference_setpoints"])
    _, info = env.reset(seed=0)
    env.step(info["reference_setpoints"])


NEXT, SAME, OFF = (gym.vector.AutoresetMode.NEXT_STEP, gym.vector.AutoresetMode.SAME_STEP,
                   gym.vector.AutoresetMode.DISABLED)  # fmt: skip


@pytest.mark.parametrize(
    ("make_vec_kwargs", "autoreset"),
    [
        ({}, NEXT),  # the defaults: MOSyncVectorEnv
        ({"autoreset_mode": SAME}, SAME),
        ({"autoreset_mode": "Disabled"}, OFF),
        ({"asynchronous": True}, NEXT),  # MOAsyncVectorEnv
        ({"asynchronous": True, "autoreset_mode": SAME}, SAME),
        ({"asynchronous": True, "autoreset_mode": OFF}, OFF),
        # gymnasium's own AsyncVectorEnv
        ({"vectorization_mode": "async", "vector_kwargs": {"worker": mo_async_worker}}, NEXT),
        ({"vectorization_mode": "async", "vector_kwargs": {"autoreset_mode": SAME}}, SAME),
        ({"vectorization_mode": "async", "vector_kwargs": {"autoreset_mode": OFF}}, OFF),
    ],
)
def test_make_vec_stacks_the_vector_rewards(make_vec_kwargs, autoreset):
    # env 0 leaves the road after 9 steps, env 1 is truncated after 40: env 0 restarts while
    # env 1 is mid-episode; the single envs on the same seeds give the expected rewards
    actions = np.array([[2.0, 1.0], [0.0, 0.0]], np.float32)
    venv = gym.make_vec(ENV_ID, num_envs=2, action_type="control", **SHORT, **make_vec_kwargs)
    singles = [GridSimEnv(action_type="control", **SHORT) for _ in range(2)]
    try:
        assert venv.metadata["autoreset_mode"] is autoreset
        venv.reset(seed=[1, 2])
        for env, seed in zip(singles, [1, 2], strict=True):
            env.reset(seed=seed)
        due = np.zeros(2, bool)  # NEXT_STEP: the next step resets
        ends = np.zeros(2, int)
        for _ in range(42):
            obs, r, term, trunc, info = venv.step(actions)
            assert r.shape == (2, 3) and r.dtype == np.float64
            for i, env in enumerate(singles):
                if due[i]:  # the autoreset step: a zero vector
                    seen, _ = env.reset()
                    reward, ended = np.zeros(3), False
                    assert not (term[i] or trunc[i])
                else:
                    seen, reward, te, tr, _ = env.step(actions[i])
                    assert (te, tr) == (term[i], trunc[i])
                    ended = te or tr
                    if ended and autoreset is SAME:
                        seen, _ = env.reset()
                np.testing.assert_array_equal(r[i], reward)
                np.testing.assert_array_equal(obs["grids"][i], seen["grids"])
                due[i] = ended and autoreset is NEXT
                ends[i] += ended
            if autoreset is OFF and (term | trunc).any():
                venv.reset(options={"reset_mask": term | trunc})
                for env in np.array(singles)[term | trunc]:
                    env.reset()
        assert obs["grids"].shape == (2, 5, 128, 128)
        assert ends[0] >= 3 and ends[1] == 1
    finally:
        venv.close()


def test_make_vec_steps_its_environments_phase_by_phase(monkeypatch):
    """The default vector env steps its GridSimEnv with ``step_all`` (the live ones only, on a
    NEXT_STEP autoreset step); one of other environments steps them in turn."""
    from gridsim.envs import vector

    calls = []

    def spy(envs, actions):
        calls.append(len(envs))
        return step_all(envs, actions)

    monkeypatch.setattr(vector, "step_all", spy)
    actions = np.array([[2.0, 1.0], [0.0, 0.0]], np.float32)  # env 0 leaves the road at 9
    venv = gym.make_vec(ENV_ID, num_envs=2, action_type="control", **SHORT)
    venv.reset(seed=[1, 2])
    for _ in range(11):
        venv.step(actions)
    assert calls == [2] * 9 + [1, 2]  # env 0's autoreset step: env 1 alone
    wrapped = vector.MOSyncVectorEnv(
        [lambda: gym.wrappers.RecordEpisodeStatistics(GridSimEnv(**SHORT))] * 2
    )
    wrapped.reset(seed=[1, 2])
    wrapped.step(wrapped.action_space.sample())
    assert len(calls) == 11


@pytest.mark.parametrize(
    ("mode", "vector_kwargs"),
    [
        ("sync", None),
        ("sync", {"autoreset_mode": SAME}),
        ("async", None),  # NEXT_STEP, the default
        ("async", {"autoreset_mode": "NextStep"}),
    ],
)
def test_make_vec_refuses_gymnasium_vector_envs_that_drop_the_reward_vector(mode, vector_kwargs):
    with pytest.raises(ValueError) as info:
        gym.make_vec(ENV_ID, num_envs=2, vectorization_mode=mode, vector_kwargs=vector_kwargs,
                     **SHORT)  # fmt: skip
    message = str(info.value)
    assert f"builds gymnasium's {mode.capitalize()}VectorEnv" in message
    assert "leave vectorization_mode unset" in message and "asynchronous=True" in message
    assert "LinearScalarization" in message


@pytest.mark.parametrize(
    ("env_id", "wrappers"),
    [
        ("gridsim:GridSim-v0", None),  # the id with its module (the docs show it)
        (ENV_ID, ["MaximisedObjectives"]),  # a wrapper that keeps the vector
        (ENV_ID, ["PlanSmoothing", "CaptionedRender"]),
    ],
)
def test_make_vec_refuses_them_whatever_the_id_and_with_wrappers_that_keep_the_vector(
    env_id, wrappers
):
    """The guard compared the id with "GridSim-v0" and trusted any wrapper: the module's
    id and GridSim's own vector-keeping wrappers built gymnasium's vector envs that failed
    at the first step (sync) or at an autoreset (async), or stacked [0.0, 0.0]."""
    from gridsim.envs import wrappers as ours

    given = None if wrappers is None else [getattr(ours, name) for name in wrappers]
    for mode in ("sync", "async"):
        with pytest.raises(ValueError, match=f"builds gymnasium's {mode.capitalize()}VectorEnv"):
            gym.make_vec(env_id, num_envs=2, vectorization_mode=mode, wrappers=given, **SHORT)


def test_gridsims_wrappers_record_their_arguments_so_that_gym_make_rebuilds_them():
    """gymnasium's check_env refused LinearScalarization (and the spec lost ``weights``
    and ``keep``: ``gym.make(env.spec)`` raised): they record their arguments."""
    from gymnasium.utils.env_checker import check_env

    from gridsim.envs.wrappers import CaptionedRender, MaximisedObjectives, PlanSmoothing

    env = LinearScalarization(gym.make(ENV_ID), weights=(-0.01, -0.5, 0.1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # (check_env: "use env.unwrapped")
        check_env(env)
    again = gym.make(env.spec)
    assert isinstance(again, LinearScalarization) and list(again.weights) == [-0.01, -0.5, 0.1]
    assert gym.make(PlanSmoothing(gym.make(ENV_ID), 0.5).spec).smoother.keep == 0.5
    assert isinstance(gym.make(MaximisedObjectives(gym.make(ENV_ID)).spec), MaximisedObjectives)
    shown = CaptionedRender(gym.make(ENV_ID, render_mode="rgb_array"), label="mine")
    assert gym.make(shown.spec).label == "mine"


def test_make_vec_does_not_refuse_another_env_that_wraps_gridsim():
    # a scalar-reward env registered under its own id may build GridSim-v0 inside
    env_id = "ScalarGridSimForTests-v0"
    if env_id not in gym.registry:
        gym.register(env_id, entry_point=lambda **kw: LinearScalarization(make(**kw)))
    venv = gym.make_vec(env_id, num_envs=2, vectorization_mode="sync")
    try:
        venv.reset(seed=[1, 2])
        assert venv.step(venv.action_space.sample())[1].shape == (2,)
    finally:
        venv.close()


def test_make_vec_with_gymnasiums_sync_vector_env_and_a_scalarising_wrapper():
    venv = gym.make_vec(ENV_ID, num_envs=2, vectorization_mode="sync",
                        wrappers=[LinearScalarization], **SHORT)  # fmt: skip
    try:
        venv.reset(seed=[1, 2])
        assert venv.step(venv.action_space.sample())[1].shape == (2,)
    finally:
        venv.close()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"num_envs": 0}, "num_envs must be an integer >= 1, got 0"),
        ({"asynchronous": "yes"}, "asynchronous must be True or False, got 'yes'"),
        ({"autoreset_mode": "next"}, r"autoreset_mode must be one of .*'SameStep'.*got 'next'"),
    ],
)
def test_make_vec_arguments_are_checked(kwargs, match):
    with pytest.raises(ValueError, match=match):
        gym.make_vec(ENV_ID, **{"num_envs": 2, **kwargs})


def test_reward_space_is_reachable_on_the_made_env():
    env = gym.make(ENV_ID)
    assert env.reward_space.shape == (3,) and env.reward_space is env.unwrapped.reward_space
    with pytest.raises(RuntimeError, match="reset"):
        env.step(env.action_space.sample())


def test_compiled_setpoint_path_equals_numpy():
    """The trajectory action's compiled clip, grid -> world map and path (points within 1 mm
    of the one before dropped, as a polyline) give the same bits as the NumPy code they
    replaced."""
    import math

    from gridsim.envs.actions_kernels import setpoint_path
    from gridsim.frames import grid_to_world
    from gridsim.road.polyline import Polyline

    env = GridSimEnv()
    box = env.action_space
    rng = np.random.default_rng(21)
    for _ in range(2000):
        a = rng.normal(0, 1, (5, 2)) * rng.choice([1e-4, 1.0, 20.0, 200.0])
        a[rng.random(5) < 0.2] = 0.0  # repeated points
        ego, rotation = rng.uniform(-1e3, 1e3, 2), float(rng.choice([0.0, rng.uniform(-4, 4)]))
        pts = grid_to_world(np.clip(a, box.low, box.high), ego, rotation)
        path_pts = np.vstack([ego, pts])
        keep = np.concatenate([[True], np.hypot(*np.diff(path_pts, axis=0).T) > 1e-3])
        got, first, arrays = setpoint_path(a, box.low, box.high, float(ego[0]), float(ego[1]),
                                           math.cos(rotation), math.sin(rotation))  # fmt: skip
        assert np.array_equal(got, pts)
        assert first == float(np.hypot(*(pts[0] - ego)))
        assert np.array_equal(arrays[0], path_pts[keep])
        if keep.sum() >= 2:
            want, path = Polyline(path_pts[keep]), Polyline.from_segments(arrays)
            for name in Polyline.__slots__:
                assert np.array_equal(getattr(path, name), getattr(want, name)), name


def test_a_vector_option_given_as_an_env_keyword_says_where_it_goes():
    message = r"shared_memory: an option of gymnasium's vector env, not a scenario key: "
    with pytest.raises(ScenarioError, match=message + r".*vector_kwargs"):
        gym.make_vec(ENV_ID, num_envs=2, shared_memory=False)


@pytest.mark.slow
def test_the_start_method_of_asynchronous_vector_envs_is_chosen_with_context():
    venv = gym.make_vec(ENV_ID, num_envs=1, asynchronous=True, context="spawn",
                        action_type="control", simulation={"duration": 1.0})  # fmt: skip
    try:
        venv.reset(seed=0)
        _, rewards, *_ = venv.step(venv.action_space.sample())
        assert rewards.shape == (1, 3)
    finally:
        venv.close()
    with pytest.raises(ValueError, match="start method of the subprocesses of asynchronous=True"):
        gym.make_vec(ENV_ID, num_envs=1, context="spawn")
    with pytest.raises(ValueError, match="context must be one of"):
        gym.make_vec(ENV_ID, num_envs=1, asynchronous=True, context="teleport")


@pytest.mark.parametrize("asynchronous", [False, True])
def test_a_batch_of_the_wrong_length_is_refused_before_any_environment_steps(asynchronous):
    """gymnasium's asynchronous step sent each worker its action before it found a batch of
    3 for 2 environments too long: the batch said to be refused was stepped, and every later
    step answered the one before. The in-process one said ``zip() argument 2 is shorter``.
    Both name the batch's shape now, and nothing moves."""
    venv = gym.make_vec(ENV_ID, num_envs=2, asynchronous=asynchronous, action_type="control",
                        simulation={"duration": 2.0})  # fmt: skip
    try:
        venv.reset(seed=0)
        for wrong in (np.tile([[1.5, 0.5]], (3, 1)), np.zeros((1, 2)), np.zeros(2), 1.0):
            with pytest.raises(ValueError, match=r"a vector of 2 environments steps a batch of "
                               r"actions of shape \(2, 2\) \(one per environment"):  # fmt: skip
                venv.step(np.asarray(wrong, np.float32))
        obs, _, _, _, info = venv.step(np.zeros((2, 2), np.float32))
        np.testing.assert_array_equal(info["time"], [0.1, 0.1])  # the first step taken
        np.testing.assert_array_equal(obs["ego"][:, 2:4], 0.0)  # its (zero) controls
    finally:
        venv.close()


def test_the_distribution_has_one_version_and_ships_its_type_marks():
    import importlib.metadata

    import gridsim
    import neurotrajectory

    assert neurotrajectory.__version__ == gridsim.__version__
    assert f"## {gridsim.__version__} (" in (ROOT / "CHANGELOG.md").read_text()
    assert importlib.metadata.version("gridsim") == gridsim.__version__  # pyproject reads it
    for package in (gridsim, neurotrajectory):
        assert (Path(package.__file__).parent / "py.typed").is_file()


def test_the_modules_the_docs_name_are_reachable_after_import_gridsim():
    """``gridsim.envs.wrappers.LinearScalarization`` as environment.md and make_vec's
    message write it, in a fresh interpreter that imported nothing but ``gridsim``."""
    code = (
        "import gridsim; gridsim.envs.wrappers.LinearScalarization; "
        "gridsim.envs.vector.mo_async_worker; gridsim.envs.observations.ObservationType"
    )
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, timeout=120)
    with pytest.raises(AttributeError, match="module 'gridsim.envs' has no attribute 'nope'"):
        import gridsim.envs

        gridsim.envs.nope  # noqa: B018


@pytest.mark.parametrize(
    ("kwargs", "meant"),
    [
        ({"obsrvation_type": "grid"}, "observation_type"),
        ({"trafic": {}}, "traffic"),
        ({"asynchronus": True}, "asynchronous"),
    ],  # fmt: skip
)
def test_a_misspelt_option_is_named_with_its_closest_spelling(kwargs, meant):
    from gridsim.errors import ScenarioError

    (key,) = kwargs
    with pytest.raises(
        ScenarioError, match=rf"no option '{key}' \(did you mean '{meant}'\?\)\. Its"
    ):
        gym.make("GridSim-v0", **kwargs)


def test_a_seed_given_to_make_says_where_seeds_go():
    from gridsim.errors import ScenarioError

    with pytest.raises(ScenarioError, match=r"no option 'seed' \(an episode's seed is reset\(seed"):
        gym.make("GridSim-v0", seed=3)


def test_an_episode_is_replayed_from_its_info_episode_seed():
    """``info["episode_seed"]`` of an unseeded episode rebuilds it: ``reset(options=
    {"episode_seed": S})`` in another env gives the same observations and steps, bit for bit
    (``reset(seed=S)`` does not: the reset seed seeds the stream the episode seed is drawn
    from). The option leaves the stream as a plain reset would, and bad options are refused
    without touching the env's episode."""
    first = gym.make("GridSim-v0")
    first.reset(seed=5)
    _, info = first.reset()  # unseeded, after a seeded one
    wanted = info["episode_seed"]
    first.action_space.seed(1)
    actions = [first.action_space.sample() for _ in range(4)]
    steps = [first.step(a) for a in actions]
    again = gym.make("GridSim-v0")
    obs, info2 = again.reset(options={"episode_seed": wanted})
    assert info2["episode_seed"] == wanted
    for a, (obs1, r1, *_rest) in zip(actions, steps, strict=True):
        obs2, r2, *_ = again.step(a)
        assert all(np.array_equal(obs1[k], obs2[k]) for k in obs1)
        assert np.array_equal(r1, r2)
    # the stream goes on as after a plain reset: the next unseeded episode is the same
    plain, replayed = gym.make("GridSim-v0"), gym.make("GridSim-v0")
    plain.reset(seed=9)
    replayed.reset(seed=9, options={"episode_seed": wanted})
    assert plain.reset()[1]["episode_seed"] == replayed.reset()[1]["episode_seed"]
    before = again.unwrapped.world.time
    for bad, said in (({"episode_seed": 1.5}, "takes an int"), ({"episode_sed": 3}, "no option"),
                      ({"episode_seed": -1}, r"must be in \[0, 2\*\*31 - 1\)")):  # fmt: skip
        with pytest.raises(ValueError, match=said):
            again.reset(options=bad)
    assert again.unwrapped.world.time == before


def test_step_all_gives_what_stepping_one_after_another_gives():
    """``step_all`` runs each phase of a step for every environment in turn (the shared
    tables stay in cache); each environment's results are the same, bit for bit, and an
    environment that cannot step stops them all before any moves."""
    from gridsim.envs.gridsim_env import GridSimEnv, step_all

    def make():
        envs = [GridSimEnv(sc, observation_type="grid") for sc in ("seamless", "inner_city",
                                                                    "seamless")]  # fmt: skip
        infos = [env.reset(seed=s)[1] for env, s in zip(envs, (3, 4, 3), strict=True)]
        return envs, infos

    (alone, a_infos), (together, t_infos) = make(), make()
    for _ in range(25):
        live = [k for k in range(3) if not (alone[k]._terminated or alone[k]._truncated)]
        actions = [a_infos[k]["reference_setpoints"] + 0.3 * k for k in live]
        one = [alone[k].step(a) for k, a in zip(live, actions, strict=True)]
        both = step_all([together[k] for k in live], actions)
        for k, x, y in zip(live, one, both, strict=True):
            assert np.array_equal(x[0]["grid"], y[0]["grid"]) and np.array_equal(x[1], y[1])
            assert x[2:4] == y[2:4] and np.array_equal(x[4]["pose"], y[4]["pose"])
            a_infos[k], t_infos[k] = x[4], y[4]
    ended = GridSimEnv("seamless", simulation={"duration": 0.1})
    _, info = ended.reset(seed=0)
    ended.step(info["reference_setpoints"])  # truncated: its time is up
    fresh = GridSimEnv("seamless")
    _, info = fresh.reset(seed=0)
    before = fresh.world.ego.copy()
    with pytest.raises(RuntimeError, match="reached its time limit"):
        step_all([fresh, ended], [info["reference_setpoints"]] * 2)
    assert np.array_equal(fresh.world.ego, before)  # nothing moved
    other = GridSimEnv("seamless")
    other.reset(seed=1)
    with pytest.raises(ValueError, match="trajectory action must have shape"):
        step_all([fresh, other], [info["reference_setpoints"], np.zeros(3)])
    assert np.array_equal(fresh.world.ego, before) and fresh.world.time == 0.0  # checked first
    with pytest.raises(ValueError, match="2 environments and 1 actions"):
        step_all([fresh, fresh], [info["reference_setpoints"]])
    with pytest.raises(ValueError, match="an environment is listed twice"):
        step_all([fresh, fresh], [info["reference_setpoints"]] * 2)
    with pytest.raises(ValueError, match="give env.unwrapped"):
        step_all([gym.wrappers.TimeLimit(fresh, 5)], [info["reference_setpoints"]])
