"""Headless rendering and video export."""

import contextlib
import functools
import io
import json
import tempfile
from pathlib import Path

import gymnasium as gym
import imageio.v3 as iio
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gridsim.cli import main
from gridsim.envs import ENV_ID
from gridsim.errors import GridSimError
from gridsim.policies import Reference
from gridsim.video import VideoWriter, record_rollout


def test_a_plan_is_drawn_beside_the_human_set_points_it_was_scored_against():
    """After a step the frame shows the plan with the reference l1 compared it with (not the
    human's next set-points, 0.1 s further on): a plan that is the human's covers them."""
    env = gym.make(ENV_ID, render_mode="rgb_array")
    drawn = []
    renderer = env.unwrapped.renderer
    render = renderer.render
    renderer.render = lambda world, grid, overlay, **kw: (
        drawn.append(overlay) or render(world, grid, overlay, **kw)
    )
    _, info = env.reset(seed=0)
    env.render()
    assert [style for *_, style in drawn[-1]] == ["ring"]  # the human's, no plan
    for _ in range(3):
        _, _, _, _, info = env.step(info["reference_setpoints"])
        env.render()
        (reference, magenta, ring), (plan, yellow, dot) = drawn[-1]  # the plan over the rings
        assert (magenta, ring) == ((255, 80, 255), "ring") and (yellow, dot) == (
            (255, 220, 0),
            "dot",
        )
        assert info["l1"] < 1e-6 and np.abs(plan - reference).max() < 1e-3  # one on the other
        assert np.abs(reference - env.unwrapped._ref_future).max() > 0.3  # not the next ones


def test_frames_say_how_the_episode_ended_and_videos_who_drives():
    from gridsim.render.annotations import ENDED_COLOUR, Caption, annotate
    from gridsim.video import policy_name

    env = gym.make(ENV_ID, render_mode="rgb_array")
    _, info = env.reset(seed=0)
    frame = env.render()
    assert Caption.from_info(info, None, None).ended is None
    crash = {**info, "collision": True, "time": 7.25}
    caption = Caption.from_info(crash, None, None)
    assert caption.ended == "collision"
    assert Caption.from_info({**info, "off_road": True}, None, None).ended == "off the road"
    marked = annotate(frame.copy(), caption, 8.0)
    unmarked = annotate(frame.copy(), Caption.from_info({**info, "time": 7.25}, None, None), 8.0)
    rows, cols = (np.flatnonzero(np.any(marked != unmarked, axis=a)) for a in ((1, 2), (0, 2)))
    # the caption's last line, top left: nothing of the scene is covered at the end
    assert rows.max() < 60 and cols.max() < 300
    assert np.any(np.all(marked[:60, :300] == ENDED_COLOUR, axis=-1))  # in its colour
    # a frame without set-points (gridsim drive) does not list their colours
    plain = annotate(frame.copy(), caption, 8.0, setpoints=False)
    from gridsim.render.topdown import PLAN_COLOUR

    legend = np.s_[380:, :140]
    assert np.any(np.all(marked[legend] == PLAN_COLOUR, axis=-1))  # the plan's dot
    assert not np.any(np.all(plain[legend] == PLAN_COLOUR, axis=-1))

    def my_planner(env, obs, info):
        return info["reference_setpoints"]

    assert policy_name(my_planner) == "my_planner" and policy_name(Reference()) == "Reference"
    assert policy_name(lambda env, obs, info: None) == "a lambda policy"
    assert policy_name(functools.partial(my_planner)) == "my_planner"
    # an episode that reached its time limit says so on its last frame
    assert Caption.from_info(info, None, None, timed_out=True).ended == "time limit"
    from gridsim.render.annotations import annotate_env_frame

    short = gym.make(ENV_ID, render_mode="rgb_array", simulation={"duration": 0.3})
    u = short.unwrapped

    def with_and_without_ending(info):
        frame, fitness = short.render(), np.zeros(3)
        plain = annotate(frame.copy(), Caption.from_info(info, None, fitness),
                         u.renderer.scale, u.renderer.view.inset_size)  # fmt: skip
        return annotate_env_frame(short, frame.copy(), info, None, fitness), plain

    _, info = short.reset(seed=0)
    marked, plain = with_and_without_ending(info)
    assert np.array_equal(marked, plain)  # the first frame: no ending
    for _ in range(3):
        _, _, terminated, truncated, info = short.step(short.unwrapped.reference_in_grid(
            short.unwrapped.world.time + u.cfg.env.setpoint_times))  # fmt: skip
    assert truncated and not terminated
    marked, plain = with_and_without_ending(info)
    assert not np.array_equal(marked, plain)  # the banner


def test_the_grid_inset_outlines_the_ego_where_the_grid_has_it():
    """The inset's white outline is the ego's footprint in the grid: at its centre (the rear
    axle, with the footprint ahead of it), turned with the ego on a north-up grid."""
    env = gym.make(ENV_ID, render_mode="rgb_array")
    _, info = env.reset(seed=0)
    frame = env.render()
    inset = frame[8:168, 472:632]
    white = np.argwhere(inset.min(axis=-1) > 120)  # (anti-aliased: whitish, not white)
    assert len(white) > 10
    rows, cols = white[:, 0], white[:, 1]
    assert 70 < rows.mean() < 90 and 75 < cols.mean() < 95  # at the centre, ahead of the axle
    assert np.ptp(cols) > np.ptp(rows)  # the seamless ego starts heading east: lying flat


def test_the_inset_legend_says_a_heading_up_grid_turns_with_the_ego(monkeypatch):
    """A heading-up grid's inset points the ego up while the frame is north up: nothing said
    so. The legend says the grid's orientation, and the frames of such a scenario use it."""
    from gridsim.render import annotations

    assert annotations.inset_legend("north_up")[0][0] == "sensor grid (north up):"
    assert annotations.inset_legend("heading_up")[0][0] == "sensor grid (heading up):"
    said = []
    real = annotations.inset_legend
    monkeypatch.setattr(annotations, "inset_legend", lambda o: said.append(o) or real(o))
    env = gym.make(ENV_ID, render_mode="rgb_array", sensor={"orientation": "heading_up"})
    _, info = env.reset(seed=0)
    annotations.annotate_env_frame(env, env.render(), info, None, np.zeros(3))
    assert said == ["heading_up", "heading_up"]  # (the frame keeps clear of it; it writes it)


def test_render_returns_frames_with_grid_inset_and_setpoints():
    env = gym.make(ENV_ID, render_mode="rgb_array")
    obs, info = env.reset(seed=0)
    env.step(info["reference_setpoints"] + np.array([0.0, 1.0], np.float32))
    frame = env.render()
    assert frame.shape == (480, 640, 3) and frame.dtype == np.uint8
    inset = frame[8:168, 472:632]
    assert (inset[..., 1] == 200).any()  # free cells (green) in the grid inset
    assert np.all(frame == (255, 220, 0), axis=-1).any()  # the commanded plan
    assert np.all(frame == (255, 255, 255), axis=-1).any()  # the reference set-points
    plain = gym.make(ENV_ID)
    plain.reset(seed=0)
    assert plain.render() is None  # no render mode: nothing, and never a window


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_rollout_video_is_readable_with_the_right_frame_count(tmp_path, suffix):
    env = gym.make(ENV_ID, render_mode="rgb_array", simulation={"duration": 3.0})
    path, infos = record_rollout(env, Reference(), tmp_path / f"run{suffix}", steps=100, seed=1)
    assert path.suffix == suffix and len(infos) == 30  # the episode ends at 3 s
    frames = iio.imread(path, index=None)
    assert len(frames) == 31  # the first frame plus one per step
    assert frames.shape[1:3] == (480, 640)
    assert all(f.std() > 10 for f in frames)  # not blank
    if suffix == ".mp4":
        meta = iio.immeta(path)
        assert meta["fps"] == pytest.approx(10.0)  # the simulation's real rate


def test_video_writer_rejects_bad_input(tmp_path):
    with pytest.raises(GridSimError, match=r"x.avi: unsupported extension '.avi'; use \.mp4"):
        VideoWriter(tmp_path / "x.avi", 10)
    (tmp_path / "afile").write_text("")
    with pytest.raises(GridSimError, match=r"afile/x.gif: .*afile is a file, not a folder"):
        VideoWriter(tmp_path / "afile" / "x.gif", 10)
    (tmp_path / "dir.gif").mkdir()
    with pytest.raises(GridSimError, match="dir.gif: is a folder, expected a file"):
        VideoWriter(tmp_path / "dir.gif", 10)
    with pytest.raises(GridSimError, match="fps"):
        VideoWriter(tmp_path / "x.gif", 0)
    with VideoWriter(tmp_path / "x.gif", 10) as v, pytest.raises(GridSimError, match="uint8"):
        v.write(np.zeros((4, 4), np.float32))
    env = gym.make(ENV_ID)
    with pytest.raises(GridSimError, match="render_mode='rgb_array'"):
        record_rollout(env, Reference(), tmp_path / "y.gif", 3)
    with pytest.raises(GridSimError, match="steps must be >= 1, got 0"):
        record_rollout(env, Reference(), None, 0)


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_frames_of_odd_sizes_make_a_video_and_frames_of_another_size_are_refused(tmp_path, suffix):
    """H.264 takes even sizes only: 127 x 77 frames made the MP4 encoder fail with "did the
    disk fill up?" or a broken pipe. They are written with their last row and column again;
    a frame of another size than the first is refused, naming both."""
    path = tmp_path / f"odd{suffix}"
    with VideoWriter(path, 10) as v:
        for k in range(3):
            v.write(np.full((127, 77, 3), 40 * k, np.uint8))
        with pytest.raises(GridSimError, match=r"frame 3 is 128 x 77 pixels, the video's are "
                           r"127 x 77 \(a video's frames have one size\)"):  # fmt: skip
            v.write(np.zeros((128, 77, 3), np.uint8))
    frames = iio.imread(path)
    assert frames.shape[1:] == ((128, 78, 3) if suffix == ".mp4" else (127, 77, 3))
    assert len(frames) == 3


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_a_video_stopped_half_way_leaves_the_earlier_one_and_no_partial_file(tmp_path, suffix):
    path = tmp_path / f"v{suffix}"
    frame = np.full((32, 48, 3), 90, np.uint8)
    with VideoWriter(path, 10) as v:
        for k in range(3):
            v.write(frame + np.uint8(40 * k))  # distinct frames (a GIF merges equal ones)
    kept = path.read_bytes()
    assert len(iio.imread(path, index=None)) == 3
    with pytest.raises(KeyboardInterrupt), VideoWriter(path, 10) as v:
        v.write(frame)
        raise KeyboardInterrupt  # Ctrl-C while filming
    assert path.read_bytes() == kept and sorted(tmp_path.iterdir()) == [path]
    env = gym.make(ENV_ID, render_mode="rgb_array", simulation={"duration": 3.0})
    with pytest.raises(GridSimError, match="steps must be"):  # fails before any frame
        record_rollout(env, Reference(), tmp_path / f"w{suffix}", steps=0)
    assert sorted(tmp_path.iterdir()) == [path]


def test_an_encoder_that_fails_to_finish_leaves_nothing(tmp_path, monkeypatch):
    frame = np.full((32, 48, 3), 90, np.uint8)
    v = VideoWriter(tmp_path / "v.gif", 10)
    v.write(frame)
    monkeypatch.setattr(v._writer, "close", lambda: (_ for _ in ()).throw(OSError("disk full")))
    with pytest.raises(OSError, match="disk full"):
        v.close()
    assert list(tmp_path.iterdir()) == []
    # aborting after an error: the encoder's own failure does not hide the error
    w = VideoWriter(tmp_path / "w.gif", 10)
    w.write(frame)
    monkeypatch.setattr(w._writer, "close", lambda: (_ for _ in ()).throw(OSError("broken")))
    with pytest.raises(KeyboardInterrupt), w:
        raise KeyboardInterrupt
    assert list(tmp_path.iterdir()) == []


def test_gymnasium_record_video_wrapper(tmp_path):
    env = gym.make(ENV_ID, render_mode="rgb_array", simulation={"duration": 2.0})
    folder = tmp_path / "videos"
    env = gym.wrappers.RecordVideo(
        env, str(folder), episode_trigger=lambda e: True, disable_logger=True
    )
    obs, info = env.reset(seed=0)
    done = False
    while not done:
        obs, r, term, trunc, info = env.step(info["reference_setpoints"])
        done = term or trunc
    env.close()
    videos = list(folder.glob("*.mp4"))
    assert len(videos) == 1
    assert len(iio.imread(videos[0], index=None)) >= 20


def test_run_drives_the_recorded_track_asked_for_and_names_it(capsys, tmp_path):
    """A recorded scene's episode lasts as long as its ego's track (2-7 s on the shipped
    scenes): the summary names the track and its length, and ``--track`` picks one."""
    assert main(["run", "--scenario", "us101_3_3", "--track", "388", "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["ego_track"] == "388" and summary["ego_track_s"] == pytest.approx(3.1)
    assert summary["simulated_s"] <= summary["ego_track_s"]
    assert main(["run", "--scenario", "us101_3_3", "--track", "9999", "--quiet"]) == 2
    assert "ego.track '9999' is not in scene 'USA_US101-3_3_T-1'; tracks: 363, 376" in \
        capsys.readouterr().err  # fmt: skip
    assert main(["run", "--scenario", "seamless", "--track", "3", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "--track 3: seamless is a generated scenario" in err
    assert "ego.track not used" not in err  # (a warning that it is ignored came first)
    fast = tmp_path / "fast.yaml"  # other warnings are given all the same
    fast.write_text("name: x\nextends: seamless\ntraffic: {v_max: 45}\n"
                    "ego: {vehicle: {v_max: 50}}\n")  # fmt: skip
    assert main(["run", "--scenario", str(fast), "--track", "3", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "traffic.v_max 45 m/s is 162 km/h" in err and "is a generated scenario" in err
    assert main(["run", "--steps", "3", "--quiet"]) == 0
    assert "ego_track" not in json.loads(capsys.readouterr().out)  # generated: no track


def test_run_command(tmp_path, capsys):
    video = tmp_path / "out.mp4"
    code = main(["run", "--scenario", "inner_city", "--steps", "40", "--policy", "lane-follow",
                 "--video", str(video), "--quiet"])  # fmt: skip
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["steps"] == 40 and summary["distance_m"] > 10 and not summary["collision"]
    assert summary["ended_by"] == "steps limit"  # 40 decisions of a 60 s scenario
    assert set(summary["fitness_sums"]) == {"l1", "l2", "l3"}
    assert len(iio.imread(video, index=None)) == 41
    for policy in ("idle", "random", "reference"):
        assert main(["run", "--steps", "5", "--policy", policy, "--quiet"]) == 0
    capsys.readouterr()
    short = tmp_path / "short.yaml"
    short.write_text("extends: seamless\nname: short\nsimulation: {duration: 1.0}\n")
    assert main(["run", "--scenario", str(short), "--steps", "40", "--quiet"]) == 0
    assert json.loads(capsys.readouterr().out)["ended_by"] == "time limit"
    with pytest.raises(SystemExit) as info:
        main(["run", "--steps", "0", "--quiet"])
    assert info.value.code == 2
    assert "argument --steps: expected an integer >= 1, got '0'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["run", "--seed", "-3", "--quiet"])
    assert "argument --seed: expected an integer >= 0, got '-3'" in capsys.readouterr().err


def test_videos_are_annotated_unless_asked_not_to(tmp_path):
    """Exported frames say who drives, the time, speed and fitness so far (top left), what the
    colours are (bottom left, the grid's beside them: beside the inset, top middle, it hid
    the road ahead of an ego driving up the picture, under it one driving right), and carry
    a scale bar (bottom right); nothing else of the picture changes, whatever the caption's
    width. --no-overlay leaves them plain."""
    from gridsim.envs.wrappers import CaptionedRender
    from gridsim.render.annotations import Caption
    from gridsim.video import _frame

    env = gym.make(ENV_ID, render_mode="rgb_array", simulation={"duration": 2.0})
    obs, info = env.reset(seed=0)
    plain = _frame(env, info, False, None, np.zeros(3))
    annotated = _frame(env, info, True, "my planner", np.array([1.5, 0.25, 80.0]))
    differs = np.any(plain != annotated, axis=2)
    h, w = differs.shape
    regions = np.zeros_like(differs)
    regions[:90, :330] = True  # caption
    regions[h - 120 :, :200] = True  # colour legend
    regions[h - 100 :, 140:340] = True  # the grid's legend, beside the colours'
    regions[h - 45 :, w - 130 :] = True  # scale bar
    assert differs[:60, :250].mean() > 0.05 and differs[h - 90 :, :150].mean() > 0.05
    assert differs[h - 90 :, 150:280].mean() > 0.05  # the grid's legend is there
    assert differs[h - 30 :, w - 100 :].any()
    assert not differs[~regions].any()  # the picture itself is untouched
    assert not differs[:, 310 : w - 140].any()  # the middle band, top to bottom, stays clear
    wide = _frame(env, info, True, "my planner " + "x" * 50, np.array([1.5e6, 0.25, 80.0]))
    differs = np.any(plain != wide, axis=2)
    assert not differs[90:, 310 : w - 140].any() and differs[h - 90 :, 150:280].mean() > 0.05
    lines = Caption.from_info(info, "my planner", np.array([1.5, 0.25, 80.0])).lines()
    assert lines == ["my planner", "t   0.0 s    speed  8.0 m/s",
                     "fitness so far, each summed over the ticks:",
                     "  l1 1.5 m^2   l2 0.25 rad/s   l3 80 m/s"]  # fmt: skip
    path, infos = record_rollout(env, Reference(), tmp_path / "o.gif", 3, seed=0)
    frames = iio.imread(path, index=None)
    bare, _ = record_rollout(env, Reference(), tmp_path / "p.gif", 3, seed=0, overlay=False)
    plain_frames = iio.imread(bare, index=None)
    assert len(frames) == len(plain_frames) == 4
    for a, b in zip(frames, plain_frames, strict=True):  # annotated by default: the caption
        assert a[:60, :250].mean() < 0.85 * b[:60, :250].mean()  # band darkens the top left
    # render() frames on request: the same annotation through a wrapper
    wrapped = CaptionedRender(gym.make(ENV_ID, render_mode="rgb_array"), label="my planner")
    _, info = wrapped.reset(seed=0)
    np.testing.assert_array_equal(
        wrapped.render(), _frame(wrapped.env, info, True, "my planner", np.zeros(3))
    )
    _, _, _, _, step_info = wrapped.step(info["reference_setpoints"])
    fitness = np.array([step_info["l1"], step_info["l2"], step_info["l3"]])
    np.testing.assert_array_equal(
        wrapped.render(), _frame(wrapped.env, step_info, True, "my planner", fitness)
    )
    with pytest.raises(ValueError, match="render_mode='rgb_array'"):
        CaptionedRender(gym.make(ENV_ID))


RUN_VALUES = {
    "--scenario": ["seamless", "nope", "", "afile", "afile/x.yaml"],
    "--steps": ["0", "-5", "1", "2", "x", "1e3"],
    "--seed": ["-1", "0", "3", "x"],
    "--policy": ["idle", "random", "reference", "lane-follow", "bad"],
    "--video": ["v.gif", "v.avi", "afile/v.gif", "v", "."],
}


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(st.sampled_from(sorted(RUN_VALUES)), st.integers(0, 5), max_size=5))
def test_fuzzed_run_arguments_run_or_exit_2_with_a_message(choice):
    args = ["run", "--quiet", "--steps", "2"]
    for option, k in choice.items():
        args += [option, RUN_VALUES[option][k % len(RUN_VALUES[option])]]
    with tempfile.TemporaryDirectory() as tmp, contextlib.chdir(tmp):
        Path("afile").write_text("keep")
        err = io.StringIO()
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                code = main(args)
            except SystemExit as exc:
                code = exc.code
        assert code in (0, 2), err.getvalue()
        assert Path("afile").read_text() == "keep"
        if code == 2:
            assert "error: " in err.getvalue()


def test_the_view_leads_the_ego_and_points_to_a_human_out_of_it():
    """The picture is centred ahead of the ego (what it drives in 0.8 s, at most 12 m: a
    2.5 s plan at 14 m/s stays in view); a human out of the picture gets an arrow."""
    from gridsim.render.topdown import TopDownRenderer

    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    world = env.unwrapped.world
    view = TopDownRenderer()
    x, y, psi, speed = world.ego[:4]
    lead = min(0.8 * speed, 12.0)
    np.testing.assert_allclose(view.centre(world), [x + lead * np.cos(psi),
                                                    y + lead * np.sin(psi)])  # fmt: skip
    here = view.render(world, human=world.ego[:2])
    far = view.render(world, human=world.ego[:2] + np.array([0.0, 500.0]))
    changed = np.argwhere(np.any(here != far, axis=-1))
    assert len(changed) > 30  # the arrow and its label
    assert changed[:, 0].max() < 240  # in the upper half: the human is north


def test_the_arrow_to_a_human_out_of_view_stays_clear_of_a_larger_grid_inset():
    """The arrow keeps beside the inset whatever its size (it was placed for a 160-pixel one:
    a larger inset hid it)."""
    from gridsim.render.topdown import INSET_MARGIN, REFERENCE_COLOUR, TopDownRenderer, ViewSpec

    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    world = env.unwrapped.world
    grid = env.unwrapped.newest_grid()
    for size in (160, 240):
        view = TopDownRenderer(ViewSpec(inset_size=size))
        # a human far to the east of the view's centre: the arrow points right
        east = view.centre(world) + np.array([500.0, 0.0])
        img = view.render(world, grid=grid, human=east)
        arrow = np.argwhere((img == REFERENCE_COLOUR).all(axis=-1))
        assert len(arrow) > 15, f"inset of {size} pixels: the arrow is hidden"
        assert arrow[:, 1].max() < view.view.width - size - INSET_MARGIN
    narrow = TopDownRenderer(ViewSpec(width=200, height=150, inset_size=160))  # (no room)
    narrow.render(world, grid=grid, human=narrow.centre(world) + np.array([500.0, 0.0]))


def test_a_standing_ego_shows_above_its_set_points():
    """A standing ego's set-points all lie on it: its dots and rings covered it (zoomed out
    to 2 pixels a metre, all of it). Its edges are drawn above them."""
    from gridsim.render.topdown import (
        EGO_COLOUR,
        PLAN_COLOUR,
        REFERENCE_COLOUR,
        TopDownRenderer,
        ViewSpec,
    )

    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    world = env.unwrapped.world
    view = TopDownRenderer(ViewSpec(pixels_per_metre=2.0))
    centre = np.tile(world.ego_center(), (5, 1))
    bare = view.render(world)
    covered = view.render(world, overlay=[(centre, REFERENCE_COLOUR, "ring"),
                                          (centre, PLAN_COLOUR, "dot")])  # fmt: skip
    ego = np.all(bare == EGO_COLOUR, axis=-1)
    assert np.all(covered[ego] == EGO_COLOUR, axis=-1).mean() > 0.5  # (none of it before)


def test_a_long_caption_is_wrapped_beside_the_grid_inset():
    """A scenario name of 80 characters (the most) ran on under the grid inset: the caption's
    lines are broken at spaces (a longer word where it reaches the inset), and say it all."""
    from gridsim.render.annotations import _width, _wrapped

    name = "a_very_long_scenario_name_of_a_user_" * 2 + "ending_here"
    lines = [(f"reference policy, {name} (seed 1234567890)", None, "")]
    room = 640 - 160 - 8 - 8
    wrapped = _wrapped(lines, room)
    assert len(wrapped) >= 3 and all(_width([line]) <= room for line in wrapped)
    said = "".join(text.replace(" ", "") for text, _, _ in wrapped)
    assert said == lines[0][0].replace(" ", "")
    assert _wrapped([("t 1.0 s", None, "")], room) == [("t 1.0 s", None, "")]
    # no room (a 200-pixel frame beside a 160-pixel inset): short pieces, no error
    narrow = _wrapped([("scenario: " + "x" * 40, None, ""), ("", None, "")], 24)
    assert "".join(t.strip() for t, _, _ in narrow) == "scenario:" + "x" * 40
    frame = np.zeros((200, 200, 3), np.uint8)
    from gridsim.render.annotations import Caption, annotate

    annotate(frame, Caption("x" * 80, 1.0, 2.0), 8.0, inset_size=160)


def test_vehicles_show_their_heading_and_the_destination_is_marked():
    """Each vehicle's front quarter is drawn darker (a plain box did not say which way it
    drives), and the destination handed to the planner is a diamond."""
    from gridsim.render.topdown import EGO_COLOUR, NOSE_SHADE, TopDownRenderer

    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    world = env.unwrapped.world
    view = TopDownRenderer()
    frame = view.render(world)
    a = view._affine(view.centre(world), view.scale)
    c, psi, length = world.ego_center(), world.ego[2], world.ego_params.length
    ahead = np.array([np.cos(psi), np.sin(psi)])

    def colour_at(point):
        u, v = np.rint(point @ a[:, :2].T + a[:, 2]).astype(int)
        return tuple(int(k) for k in frame[v, u])

    assert colour_at(c + 0.45 * length * ahead) == tuple(int(k * NOSE_SHADE) for k in EGO_COLOUR)
    assert colour_at(c - 0.3 * length * ahead) == EGO_COLOUR
    goal = world.ego[:2] + 15.0 * ahead
    marked = view.render(world, destination=goal)
    u, v = np.rint(goal @ a[:, :2].T + a[:, 2]).astype(int)
    changed = np.argwhere(np.any(marked != frame, axis=-1))
    assert len(changed) > 20 and np.abs(changed - [v, u]).max() <= 11  # only around it


def test_a_video_cut_by_its_steps_limit_says_so_on_its_last_frame(tmp_path, monkeypatch):
    """An episode ended by the caller's steps limit (``gridsim run --steps``) got no
    end-of-episode line, unlike one that ended itself: its last frame says "steps limit"."""
    from gridsim import video
    from gridsim.render.annotations import Caption

    flags = []
    frame = video._frame
    monkeypatch.setattr(video, "_frame", lambda *a: flags.append(a[-1]) or frame(*a))
    env = gym.make(ENV_ID, render_mode="rgb_array")
    record_rollout(env, Reference(), tmp_path / "o.gif", 3, seed=0)
    assert flags == [False, False, False, True]  # the first frame, then one a step
    _, info = env.reset(seed=0)
    assert Caption.from_info(info, None, None, stopped=True).ended == "steps limit"
    assert Caption.from_info(info, None, None, True, True).ended == "time limit"


def test_run_counts_its_progress_to_the_episodes_own_end(monkeypatch):
    """``gridsim run --steps 300`` on a recorded track of a few seconds: the bar's total is
    the episode's length (it showed 300 and stopped at 13 %), and the frames name the seed."""
    from gridsim import outputs
    from gridsim.cli.run import run_policy

    bars, labels = [], []
    make = outputs.progress_bar
    monkeypatch.setattr(outputs, "progress_bar", lambda **kw: bars.append(make(**kw)) or bars[-1])
    import gridsim.video

    record = gridsim.video.record_episode
    monkeypatch.setattr(gridsim.video, "record_episode", lambda *a, label, **kw: (
        labels.append(label), record(*a, label=label, **kw))[1])  # fmt: skip
    summary = run_policy("us101_4_1", "reference", 300, seed=5)
    assert summary["ended_by"] != "steps limit" and summary["steps"] < 300
    assert bars[0].total == round(summary["ego_track_s"] / 0.1) < 300  # the track's end
    assert bars[0].n == summary["steps"]
    assert labels[0](gym.make(ENV_ID).unwrapped).endswith(", seed 5")


def test_a_frame_zooms_out_to_show_every_set_point_and_the_destination():
    """A 2.5 s plan at highway speed (70 m) left the 80 m x 60 m view: the frame zooms out
    in steps until every set-point and the destination lie inside it, and its scale bar
    says the scale it was drawn at; a short plan keeps the view's own scale."""
    from gridsim.render.annotations import annotate_env_frame
    from gridsim.render.topdown import ZOOM_MARGIN, TopDownRenderer

    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    world = env.unwrapped.world
    view = TopDownRenderer()
    psi = world.ego[2]
    ahead = np.array([np.cos(psi), np.sin(psi)])
    near = world.ego[:2] + np.outer([5.0, 10.0, 15.0], ahead)
    view.render(world, overlay=[(near, (255, 0, 0), "dot")])
    assert view.scale == view.view.pixels_per_metre
    for reach in (70.0, 140.0):
        far = world.ego[:2] + np.outer(np.linspace(14, reach, 5), ahead)
        frame = view.render(world, overlay=[(far, (255, 0, 0), "dot")], destination=far[-1])
        assert view.scale < view.view.pixels_per_metre
        a = view._affine(view.centre(world), view.scale)
        px = far @ a[:, :2].T + a[:, 2]
        h, w = frame.shape[:2]
        assert (px >= ZOOM_MARGIN - 1).all() and (px[:, 0] <= w - ZOOM_MARGIN + 1).all()
        assert (px[:, 1] <= h - ZOOM_MARGIN + 1).all()
    # points hovering at a step's edge do not switch the scale every frame: zooming back in
    # waits for some room
    view.render(world, overlay=[(near, (255, 0, 0), "dot")])
    centre = view.centre(world)
    scales = []
    for d in (36.9, 37.1, 36.9, 37.1, 36.9, 20.0):
        view.render(world, overlay=[(centre + np.outer([d], ahead), (255, 0, 0), "dot")])
        scales.append(view.scale)
    assert scales == [8.0, 6.0, 6.0, 6.0, 6.0, 8.0]
    # nor under the grid inset (top right): a road curving up to the right hid the human's
    # set-points and the destination there
    view.render(world)
    under = centre + np.array([25.0, 15.0])  # 200 px right, 120 px up at 8 px/m
    view.render(world, destination=under)
    assert view.scale == view.view.pixels_per_metre  # (no inset)
    grid = np.zeros((128, 128), np.uint8)
    frame = view.render(world, grid=grid, destination=under)
    assert view.scale == view.view.pixels_per_metre / 2
    a = view._affine(centre, view.scale)
    u, v = under @ a[:, :2].T + a[:, 2]
    assert u < frame.shape[1] - view.view.inset_size - 8 or v > view.view.inset_size + 8
    # nor under the legends (bottom left): an urban human's last set-point and destination
    # were dimmed under the grid's legend
    from gridsim.render.annotations import legend_boxes

    for inset in (None, grid):
        for x0, y0, x1, y1 in legend_boxes(view.view.height, inset is not None):
            spot = np.array([(x0 + x1) / 2 - 320, 240 - (y0 + y1) / 2]) / 8.0  # [m] at 8 px/m
            frame = view.render(world, grid=inset, destination=centre + spot)
            assert view.scale < view.view.pixels_per_metre
            a = view._affine(centre, view.scale)
            u, v = (centre + spot) @ a[:, :2].T + a[:, 2]
            assert not any(
                b[0] <= u <= b[2] and b[1] <= v <= b[3]
                for b in legend_boxes(view.view.height, inset is not None)
            )
    # the scale bar follows: a frame drawn at a quarter of the scale shows 50 m, not 10
    _, info = env.reset(seed=0)
    frame = env.unwrapped.renderer.render(world, overlay=[(far, (255, 0, 0), "dot")])
    assert env.unwrapped.renderer.scale == view.view.pixels_per_metre / 4
    marked = annotate_env_frame(env, frame.copy(), info, None, np.zeros(3))
    bar = np.argwhere((marked[-30:, -330:] == 255).all(axis=-1))
    assert bar[:, 1].max() - bar[:, 1].min() >= 100  # 50 m at 2 px/m (10 m at 8: 80 px)


def test_a_collision_frame_rings_the_ego_and_the_car_it_hit_above_the_set_points():
    """On a collision's frame the set-points drawn over the ego and the car it hit hid them:
    both are drawn again above them, outlined."""
    from gridsim.render.topdown import COLLISION_COLOUR, EGO_COLOUR, TopDownRenderer, ViewSpec
    from gridsim.world.collision import Contact

    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    world = env.unwrapped.world
    f = world.traffic.fleet
    j = int(np.flatnonzero(f.active)[0])
    view = TopDownRenderer()
    spots = np.array([[f.x[j], f.y[j]], world.ego_center()])
    overlay = [(spots, (255, 220, 0), "dot")]
    before = view.render(world, overlay=overlay)
    last = world.last
    world.last = type(last)(last.accel, last.steer_rate, Contact(vehicles=(j,)), False)
    hit = view.render(world, overlay=overlay)
    a = view._affine(view.centre(world), view.scale)
    u, v = np.rint(spots @ a[:, :2].T + a[:, 2]).astype(int).T
    plan = (255, 220, 0)
    assert all(tuple(before[v[k], u[k]]) == plan for k in range(2))  # the dots hid them
    assert all(tuple(hit[v[k], u[k]]) != plan for k in range(2))  # now drawn above
    white = np.all(hit == COLLISION_COLOUR, axis=-1) & ~np.all(before == COLLISION_COLOUR, axis=-1)
    assert white.sum() > 40  # the outlines
    # zoomed out (2 pixels a metre) the mark is around the ego, not over it (it covered it)
    small = TopDownRenderer(ViewSpec(pixels_per_metre=2.0)).render(world)
    assert np.all(small == EGO_COLOUR, axis=-1).sum() >= 4


def test_a_video_the_encoder_did_not_finish_is_refused_and_the_old_one_kept(tmp_path):
    """A full disk: ffmpeg says "Error writing trailer" on its stderr and exits, the writer
    does not raise, and an MP4 without its index (the moov box, written last) replaced the
    good video at the path with exit status 0. Now that is an error naming the file, and the
    earlier video stays."""
    from gridsim.video import _unfinished

    rng = np.random.default_rng(0)
    good = tmp_path / "good.mp4"
    with VideoWriter(good, 10) as w:
        for _ in range(5):
            w.write(rng.integers(0, 255, (64, 64, 3), dtype=np.uint8))
    data = good.read_bytes()
    assert _unfinished(good) is None and b"moov" in data
    cut = tmp_path / "cut.mp4"
    moov = data.rindex(b"moov") - 4
    for end in (moov, moov + 8, moov + 100, len(data) - 1):  # what a full disk leaves
        cut.write_bytes(data[:end])
        assert "did not finish the MP4 file" in _unfinished(cut), end
    gif = tmp_path / "a.gif"
    with VideoWriter(gif, 10) as w:
        w.write(rng.integers(0, 255, (16, 16, 3), dtype=np.uint8))
    assert _unfinished(gif) is None
    gif.write_bytes(gif.read_bytes()[:-1])
    assert "cut short" in _unfinished(gif)

    w = VideoWriter(good, 10)
    w.write(rng.integers(0, 255, (64, 64, 3), dtype=np.uint8))
    close = w._writer.close

    def full_disk():  # the encoder ends without its index, and without an error
        close()
        w._partial.write_bytes(w._partial.read_bytes()[:100])

    w._writer.close = full_disk
    with pytest.raises(GridSimError, match=r"good\.mp4: the encoder did not finish the MP4"):
        w.close()
    assert good.read_bytes() == data  # the earlier video, as it was
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


@pytest.mark.parametrize("wrapped", [False, True])
def test_a_video_cut_by_a_wrappers_time_limit_says_so_on_its_last_frame(tmp_path, monkeypatch,
                                                                        wrapped):  # fmt: skip
    """gymnasium's ``TimeLimit`` (``max_episode_steps``) truncated the episode and its summary
    said "time limit", but the last frame had no end-of-episode line (only the scenario's own
    duration counted): both say it now, in videos and in ``CaptionedRender`` frames."""
    from gridsim.envs.wrappers import CaptionedRender
    from gridsim.render import annotations
    from gridsim.video import record_episode

    said = []
    caption = annotations.Caption.from_info
    monkeypatch.setattr(annotations.Caption, "from_info", staticmethod(
        lambda *a, **k: said.append(caption(*a, **k)) or said[-1]))  # fmt: skip
    if not wrapped:
        env = gym.make(ENV_ID, render_mode="rgb_array", max_episode_steps=4)
        episode, _ = record_episode(env, Reference(), tmp_path / "o.gif", seed=0)
        assert episode.ended_by == "time limit" and episode.steps == 4
    else:
        env = CaptionedRender(gym.wrappers.TimeLimit(
            gym.make(ENV_ID, render_mode="rgb_array"), 3))  # fmt: skip
        _, info = env.reset(seed=0)
        for _ in range(3):
            *_, truncated, info = env.step(info["reference_setpoints"])
            env.render()
        assert truncated
    assert [c.ended for c in said[-2:]] == [None, "time limit"]


def test_a_video_made_from_python_names_its_episode(tmp_path, monkeypatch):
    """``record_rollout`` captioned only "a lambda policy" (the command line names the scene
    and the seed): its default label names the driver and the episode, with its episode seed
    when it was reset without a seed, so that the video can be driven again."""
    from gridsim.render import annotations

    labels = []
    caption = annotations.Caption.from_info

    def seen(info, label, *args, **kwargs):
        labels.append(label)
        return caption(info, label, *args, **kwargs)

    monkeypatch.setattr(annotations.Caption, "from_info", staticmethod(seen))
    env = gym.make(ENV_ID, render_mode="rgb_array")
    record_rollout(env, lambda env, obs, info: info["reference_setpoints"], tmp_path / "a.gif",
                   2, seed=4)  # fmt: skip
    assert set(labels) == {"a lambda policy, seamless, seed 4"}
    labels.clear()
    record_rollout(env, Reference(), tmp_path / "b.gif", 2)
    said = labels[-1]
    assert said.startswith("Reference, seamless, episode seed ")
    episode = int(said.rsplit(" ", 1)[1])
    assert episode == env.unwrapped.episode_seed
    _, info = env.reset(options={"episode_seed": episode})  # drives it again
    assert info["episode_seed"] == episode
