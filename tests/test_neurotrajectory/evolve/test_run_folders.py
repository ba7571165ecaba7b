"""Output folders are safe: one writer at a time, a failed command leaves ``--out`` as it
was, a resumed run keeps every setting and refuses another run's checkpoint."""

import json
import re
import shutil
import warnings

import numpy as np
import pytest
from breaks import ctrl_c_at

from gridsim.errors import OutputError
from gridsim.outputs import folder_lock, new_folder
from neurotrajectory.cli import main
from neurotrajectory.evolve.runs import Run, RunError, TrainConfig

TINY = dict(preset="tiny", population=4, episodes=1, episode_seconds=2.0, seed=1)
QUICK = ["--preset", "tiny", "--population", "4", "--generations", "1", "--episodes", "1",
         "--episode-seconds", "2", "--quiet"]  # fmt: skip


def test_a_folder_has_one_writer_at_a_time(tmp_path):
    busy = r"--out .*out: in use by another process \(pid \d+"
    with (
        folder_lock(tmp_path / "out"),
        pytest.raises(OutputError, match=busy),
        folder_lock(tmp_path / "out"),
    ):
        pass
    with folder_lock(tmp_path / "out"):  # free again once the holder is done
        pass


def test_a_new_folder_appears_whole_or_not_at_all(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(RuntimeError), new_folder(out) as partial:
        (partial / "half.txt").write_text("x")
        raise RuntimeError("failed midway")
    assert not out.exists() and not any(tmp_path.iterdir())
    with new_folder(out) as partial:
        (partial / "whole.txt").write_text("x")
        assert not out.exists()
    assert [p.name for p in out.iterdir()] == ["whole.txt"] and len(list(tmp_path.iterdir())) == 1
    with pytest.raises(OutputError, match="exists and is not empty"), new_folder(out):
        pass


def test_a_run_in_a_folder_that_takes_no_file_is_not_resumed(tmp_path, capsys, monkeypatch):
    """A read-only run folder (an archive, `chattr +i`): a clear error before any work, the
    run as it was (it was an internal error on the first temporary file)."""
    from neurotrajectory.evolve import runs

    run = tmp_path / "run"
    Run.create(run, TrainConfig(generations=2, **TINY))
    before = {p.name: p.read_bytes() for p in run.iterdir()}
    monkeypatch.setattr(runs, "output_problem", lambda out, directory: f"{out} is not writable")
    assert main(["train", "--resume", str(run), "--quiet"]) == 2
    assert (f"--resume {run}: {run} is not writable: a run goes on in its own folder"
            in capsys.readouterr().err)  # fmt: skip
    assert {p.name: p.read_bytes() for p in run.iterdir()} == before


def test_a_second_train_in_the_same_folder_is_refused(tmp_path, capsys):
    run = tmp_path / "run"
    Run.create(run, TrainConfig(generations=2, **TINY))
    with folder_lock(run):  # another process training it
        assert main(["train", "--resume", str(run), "--quiet"]) == 2
    assert f"--resume {run}: in use by another process (pid " in capsys.readouterr().err


def test_a_video_inside_the_run_moves_with_it(tmp_path):
    """--video RUN/knee.mp4 was kept as given: a resumed copy overwrote the original's video,
    a moved run wrote into its old place (and a read-only original failed at the end)."""
    run = tmp_path / "run"
    Run.create(run, TrainConfig(generations=1, **TINY), video=str(run / "knee.mp4"))
    assert json.loads((run / "config.json").read_text())["after"]["video"] == "{run}/knee.mp4"
    assert Run.open(run).after["video"] == str(run / "knee.mp4")
    shutil.copytree(run, tmp_path / "copy")
    assert Run.open(tmp_path / "copy").after["video"] == str(tmp_path / "copy" / "knee.mp4")
    stale = run / ".checkpoint.npz.k3j2.tmp"  # what a killed write leaves: gone on resume
    stale.write_bytes(b"half a checkpoint")
    from neurotrajectory.evolve.runs import run_folder

    with run_folder(run, resume=True):
        assert not stale.exists() and (run / "config.json").exists()
    elsewhere = str(tmp_path / "videos" / "knee.mp4")  # outside the run: as given
    Run.open(run, video=elsewhere)._write_config()  # (as a resume does once it trains)
    assert Run.open(run).after["video"] == elsewhere


def test_heldout_into_a_run_being_trained_is_refused(tmp_path, capsys):
    """heldout --out RUN/heldout.json wrote while a train held the run (and the train then
    overwrote it: the lock was taken only without --out, which is required); a report
    written elsewhere still only reads the run."""
    run = tmp_path / "run"
    Run.create(run, TrainConfig(generations=1, **TINY)).train(progress=False)
    with folder_lock(run):  # another process training it
        args = ["heldout", "--run", str(run), "--episodes", "1"]
        assert main([*args, "--out", str(run / "heldout.json"), "--overwrite"]) == 2
        # (named by heldout's own flag: it has no --resume)
        assert f"--run {run}: in use by another process (pid " in capsys.readouterr().err
        assert main([*args, "--out", str(tmp_path / "elsewhere.json")]) == 0
    # a report is not replaced unless asked: the run's own is named as such
    assert main([*args, "--out", str(run / "heldout.json")]) == 0
    before = (run / "heldout.json").read_text()
    assert main([*args, "--out", str(run / "heldout.json")]) == 2
    assert ("heldout.json exists (the run's own report, which train writes): give another "
            "file, or --overwrite to replace it") in capsys.readouterr().err  # fmt: skip
    assert (run / "heldout.json").read_text() == before
    assert main([*args, "--out", str(tmp_path / "elsewhere.json")]) == 2
    assert main([*args, "--out", str(tmp_path / "elsewhere.json"), "--overwrite"]) == 0


def test_a_train_that_fails_before_a_generation_leaves_out_as_it_was(tmp_path, monkeypatch,
                                                                      capsys):  # fmt: skip
    def broken(self, progress=True, stop_after=None):
        raise RuntimeError("a bug in the loop")

    monkeypatch.setattr(Run, "train", broken)
    assert main(["train", *QUICK, "--out", str(tmp_path / "run")]) == 3
    assert "internal error: RuntimeError: a bug in the loop" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
    (tmp_path / "empty").mkdir()
    assert main(["train", *QUICK, "--out", str(tmp_path / "empty")]) == 3
    assert list((tmp_path / "empty").iterdir()) == [tmp_path / "empty" / ".lock"]
    monkeypatch.undo()
    assert main(["train", *QUICK, "--heldout", "0", "--out", str(tmp_path / "empty")]) == 0


def test_resume_keeps_the_runs_heldout_and_video_settings(tmp_path):
    run = tmp_path / "run"
    Run.create(run, TrainConfig(generations=2, **TINY), heldout=3).train(progress=False,
                                                                        stop_after=1)  # fmt: skip
    assert json.loads((run / "config.json").read_text())["after"] == {"heldout": 3, "video": None}
    assert main(["train", "--resume", str(run), "--quiet"]) == 0
    report = json.loads((run / "heldout.json").read_text())
    assert report["network"]["episodes"] == 3  # not the default 20


def test_resume_refuses_the_checkpoint_of_another_run(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    Run.create(a, TrainConfig(generations=2, **TINY)).train(progress=False, stop_after=1)
    Run.create(b, TrainConfig(generations=2, **{**TINY, "seed": 2})).train(progress=False,
                                                                          stop_after=1)  # fmt: skip
    shutil.copy(a / "checkpoint.npz", b / "checkpoint.npz")
    with pytest.raises(RunError, match=r"b/checkpoint.npz: the checkpoint of another run"):
        Run.open(b).train(progress=False)
    shutil.copy(a / "history.json", b / "history.json")
    with pytest.raises(RunError, match=r"b/history.json: the history of another run"):
        Run.open(b).train(progress=False)
    with np.load(a / "checkpoint.npz") as data:
        assert str(data["run"]) == Run.open(a).fingerprint


def test_record_that_fails_leaves_out_as_it_was(tmp_path, monkeypatch, capsys):
    def broken(*args, **kwargs):  # after the shards are written, before the manifest
        raise RuntimeError("disk trouble")

    monkeypatch.setattr("neurotrajectory.data.storage.ShardWriter.finish", broken)
    out = tmp_path / "ds"
    assert main(["record", "--scenario", "seamless", "--episodes", "1", "--out", str(out)]) == 3
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_evaluate_refuses_a_group_named_twice(tmp_path, capsys):
    argv = ["evaluate", "--run", str(tmp_path), "--out", str(tmp_path / "ev"),
            "--group", f"a={tmp_path}", "--group", f"a={tmp_path / 'x'}"]  # fmt: skip
    assert main(argv) == 2
    assert "--group a is given twice" in capsys.readouterr().err
    assert main([*argv[:5], "--groups", "urban", "urban"]) == 2
    assert "--groups names urban more than once" in capsys.readouterr().err
    assert main([*argv[:5], "--group", f"../../etc={tmp_path}"]) == 2
    assert "group name '../../etc': use letters" in capsys.readouterr().err
    assert not (tmp_path / "ev").exists()


def test_drive_writes_a_new_folder_whole(tmp_path, capsys):
    from gridsim.cli import main as gridsim_main

    out = tmp_path / "drive"
    assert gridsim_main(["drive", "--seconds", "1", "--out", str(out), "--quiet"]) == 0
    assert (out / "summary.json").is_file() and sorted(p.name for p in tmp_path.iterdir()) == [
        "drive"
    ]
    assert gridsim_main(["drive", "--seconds", "1", "--out", str(out), "--quiet"]) == 2
    assert "exists and is not empty" in capsys.readouterr().err
    assert gridsim_main(["drive", "--seconds", "1", "--out", "", "--quiet"]) == 2
    assert "--out is empty" in capsys.readouterr().err


def test_record_refuses_a_test_fraction_without_a_split(tmp_path, capsys):
    argv = ["record", "--scenario", "seamless", "--test-fraction", "0.2", "--out",
            str(tmp_path / "ds")]  # fmt: skip
    assert main(argv) == 2
    assert "--test-fraction 0.2 sets the test side of --split" in capsys.readouterr().err
    assert not (tmp_path / "ds").exists()


@pytest.mark.parametrize(("field", "before"), list(TrainConfig.UNSTAMPED_DEFAULTS.items()))
def test_runs_saved_before_a_later_field_keep_their_fingerprint(tmp_path, field, before):
    run = Run.create(tmp_path / "run", TrainConfig(preset="tiny"))
    doc = json.loads((run.out / "config.json").read_text())
    del doc["train"][field]  # as a run saved before the field existed
    (run.out / "config.json").write_text(json.dumps(doc))
    old = Run.open(run.out)
    assert getattr(old.config, field) == before and old.fingerprint == run.fingerprint


def test_a_new_run_stopped_after_its_warm_start_keeps_it_and_resumes_as_if_uninterrupted(
    tmp_path, monkeypatch, capsys
):
    """Interrupted in generation 0, a new run keeps its warm start (minutes to fit on a big
    recipe), says how to go on, and its resume uses it without fitting it again: the same
    generations as a run never interrupted."""
    from neurotrajectory.evolve.backends import LocalBackend

    warm = [*QUICK[:-1], "--generations", "2", "--pretrain-episodes", "2", "--pretrain-epochs",
            "1", "--heldout", "0", "--quiet"]  # fmt: skip
    assert main(["train", *warm, "--out", str(tmp_path / "a")]) == 0
    evaluate = LocalBackend.evaluate

    def interrupted(self, *args, **kwargs):
        raise KeyboardInterrupt

    out = tmp_path / "b"
    monkeypatch.setattr(LocalBackend, "evaluate", interrupted)
    capsys.readouterr()
    assert main(["train", *warm, "--out", str(out)]) == 130
    err = capsys.readouterr().err
    assert err == (f"neurotrajectory: interrupted; {out} keeps its warm start (not fitted "
                   f"again); go on with: neurotrajectory train --resume {out}\n")  # fmt: skip
    assert (out / "warm_start.npz").exists() and not (out / "checkpoint.npz").exists()

    # failed after the warm start: the folder stays, and the note says so beside the error
    def broken(self, *args, **kwargs):
        raise RuntimeError("a bug in generation 0")

    monkeypatch.setattr(LocalBackend, "evaluate", broken)
    again = tmp_path / "c"
    assert main(["train", *warm, "--out", str(again)]) == 3
    err = capsys.readouterr().err
    assert err.startswith(f"neurotrajectory: note: {again} keeps its warm start (not fitted "
                          "again); go on with: neurotrajectory train --resume ")  # fmt: skip
    assert "internal error: RuntimeError: a bug in generation 0" in err
    assert (again / "warm_start.npz").exists()
    # a new run given the folder of another: the plain error, no note about that run
    assert main(["train", *warm, "--out", str(tmp_path / "a")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"neurotrajectory: error: --out {tmp_path / 'a'}: exists and is not")
    assert "note" not in err

    def fitted_again(self, probe):
        raise AssertionError("the warm start was fitted again")

    monkeypatch.setattr(LocalBackend, "evaluate", evaluate)
    monkeypatch.setattr(Run, "_warm_start", fitted_again)
    assert main(["train", "--resume", str(out), "--quiet"]) == 0

    def generations(run):
        return [h["fitness"] for h in json.loads((run / "history.json").read_text())["generations"]]

    assert generations(out) == generations(tmp_path / "a")

    # interrupted later, the note counts the finished generations
    monkeypatch.setattr(LocalBackend, "evaluate", interrupted)
    assert main(["train", "--resume", str(out), "--generations", "3", "--quiet"]) == 130
    assert "keeps its 2 finished generations; go on with" in capsys.readouterr().err


def test_train_says_what_it_does_between_its_progress_bars(tmp_path, capsys):
    """The warm start's recording, fit and result, the final choice, the held-out drive and
    the video are announced on stderr as they start (they take minutes on a recipe); --quiet
    says none of it."""
    flags = [*QUICK[:-1], "--generations", "1", "--pretrain-episodes", "2", "--pretrain-epochs",
             "1", "--validation-episodes", "2", "--heldout", "1"]  # fmt: skip
    assert main(["train", *flags, "--video", str(tmp_path / "k.gif"), "--out",
                 str(tmp_path / "a")]) == 0  # fmt: skip
    said = [line.split(": ", 1)[1].split(":")[0] for line in capsys.readouterr().err.splitlines()
            if line.startswith("neurotrajectory: ")]  # fmt: skip
    assert said == ["warm start", "warm start", "warm start", "choosing the final front",
                    "driving the knee, its warm start and the destination curve on 1 held-out "
                    "episodes", "filming the knee on a held-out episode"]  # fmt: skip
    assert main(["train", *flags, "--quiet", "--out", str(tmp_path / "b")]) == 0
    assert "neurotrajectory: " not in capsys.readouterr().err
    cold = [*QUICK[:-1], "--generations", "1", "--validation-episodes", "2", "--heldout", "1"]
    assert main(["train", *cold, "--out", str(tmp_path / "c")]) == 0  # no warm start
    assert ("neurotrajectory: driving the knee and the destination curve on 1 held-out "
            "episodes") in capsys.readouterr().err  # fmt: skip


def test_a_run_resumes_only_on_the_files_it_began_with(tmp_path, capsys):
    """A scenario folder whose trajectory file was edited, or that was given another scenario
    file since the run began: --resume names what changed instead of training on (silently)
    other data."""
    from scenes import MAP, track, write_scene

    scenes = tmp_path / "scenes"
    scenes.mkdir()
    tracks = [track(name, np.linspace(x, x + 40.0, 41), np.full(41, 1.75))
              for name, x in (("ego", 20.0), ("ahead", 60.0), ("third", 100.0))]  # fmt: skip
    scenario = write_scene(scenes, tracks, ego={"track": "random"})
    run = tmp_path / "run"
    flags = [*QUICK[:-1], "--scenario", str(scenes), "--heldout", "0", "--quiet"]
    assert main(["train", *flags, "--out", str(run)]) == 0
    kept = json.loads((run / "inputs.json").read_text())["files"]
    csv = scenes / "tracks.csv"
    assert sorted(kept) == sorted([str(scenario), str(csv), str(MAP)])
    resume = ["train", "--resume", str(run), "--generations", "2", "--quiet"]
    csv.write_text(csv.read_text().replace(",4.5,", ",4.6,", 1))  # one row's length
    shutil.copy(scenario, scenes / "another.yaml")
    config = (run / "config.json").read_text()
    assert main(resume) == 2
    err = capsys.readouterr().err
    assert (f"are not those the run began with (changed: {csv}; added: "
            f"{scenes / 'another.yaml'})" in err)  # fmt: skip
    assert "would train on other data" in err
    assert (run / "config.json").read_text() == config  # (it kept --generations 2: refused)
    # its members driven on the files of now (heldout, rollout, evaluate --run) say so
    out = tmp_path / "heldout.json"
    (scenes / "another.yaml").unlink()
    assert main(["heldout", "--run", str(run), "--episodes", "1", "--seconds", "2", "--out",
                 str(out)]) == 0  # fmt: skip
    assert f"are not those it trained on (changed: {csv}): its members are driven on the " in (
        capsys.readouterr().err)  # fmt: skip
    inputs = (run / "inputs.json").read_text()
    (run / "inputs.json").write_text(inputs[:20])  # cut short: nothing can be checked (said)
    assert main(["heldout", "--run", str(run), "--episodes", "1", "--seconds", "2", "--out",
                 str(out), "--overwrite"]) == 0  # fmt: skip
    assert "cannot be checked" in capsys.readouterr().err
    (run / "inputs.json").write_text(inputs)
    shutil.copy(scenario, scenes / "another.yaml")
    # inputs.json deleted: nothing can be checked (the edited file trains): said, and it is
    # written again, of the files as they are now
    (run / "inputs.json").unlink()
    (scenes / "another.yaml").unlink()
    assert main(["heldout", "--run", str(run), "--episodes", "1", "--seconds", "2", "--out",
                 str(out), "--overwrite"]) == 0  # fmt: skip
    assert f"{run / 'inputs.json'} is missing (deleted, or the run began with gridsim 0.2.0 " \
        "or earlier): whether the run's scenario files are those it trained on cannot be " \
        "checked" in capsys.readouterr().err  # fmt: skip
    assert main(resume) == 0
    err = capsys.readouterr().err
    assert f"{run / 'inputs.json'} is missing: whether the run's scenario files and code" in err
    assert sorted(json.loads((run / "inputs.json").read_text())["files"]) == sorted(kept)


def test_a_run_resumed_with_other_code_says_so(tmp_path, capsys, monkeypatch):
    """A run stopped, the package upgraded, the run resumed: it went on silently with
    another algorithm (its result neither code's uninterrupted run). inputs.json keeps the
    code it began with; a resume with other code warns, naming both."""
    from neurotrajectory.evolve import runs

    run = tmp_path / "run"
    flags = [*QUICK[:-1], "--heldout", "0", "--quiet"]
    assert main(["train", *flags, "--out", str(run)]) == 0
    began = json.loads((run / "inputs.json").read_text())["code"]
    assert began == runs.code_digest() and len(began["sources"]) == 16
    # an editor's lock file (a dangling link) or a hidden scratch file is not the code
    from pathlib import Path

    import gridsim

    package = Path(gridsim.__file__).parent
    lock, scratch = package / ".#outputs.py", package / ".scratch.py"
    try:
        lock.symlink_to("nobody@host.1234:1700000000")
        scratch.write_text("x = 1\n")
        assert runs.code_digest() == began
    finally:
        lock.unlink(missing_ok=True)
        scratch.unlink(missing_ok=True)
    resume = ["train", "--resume", str(run), "--generations", "2", "--quiet"]
    monkeypatch.setattr(runs, "code_digest", lambda: {"version": "9.9", "sources": "f" * 16})
    assert main(resume) == 0
    err = capsys.readouterr().err
    assert (
        f"{run} began with other code (gridsim {began['version']}, sources "
        f"{began['sources']}; now 9.9, {'f' * 16}): its next generations"
    ) in err


def test_a_skipped_file_is_named_once_by_train_and_its_workers(tmp_path, capfd):
    """train checks the data, then loads it again to use it, in each worker process too:
    the skipped file is named in one warning, not one per load (nor raw in the workers')."""
    from importlib import resources

    scenes = tmp_path / "scenes"
    scenes.mkdir()
    source = resources.files("gridsim").joinpath("data", "scenarios", "us101_4_1.yaml")
    (scenes / "us101_4_1.yaml").write_text(source.read_text())
    (scenes / "bad.xml").write_text('<?xml version="1.0"?><commonRoad')  # cut short
    flags = [*QUICK[:-1], "--scenario", str(scenes), "--heldout", "0", "--quiet",
             "--backend", "processes", "--workers", "2"]  # fmt: skip
    assert main(["train", *flags, "--out", str(tmp_path / "run")]) == 0
    err = capfd.readouterr().err
    assert err.count("bad.xml: not well-formed XML") == 1
    assert err.startswith("neurotrajectory: warning: ") and "DataWarning" not in err


def test_record_interrupted_goes_on_when_run_again(tmp_path, monkeypatch, capsys):
    """Ctrl-C keeps what ``record`` wrote until its last checkpoint (a failure does not:
    above); the same command then goes on from there, and --out is the dataset recorded
    without a break."""
    from neurotrajectory.data import recording, windows

    monkeypatch.setattr(recording, "CHECKPOINT_SECONDS", 0.0)
    argv = ["record", "--scenario", "seamless", "--episodes", "3", "--episode-seconds", "3",
            "--quiet", "--out"]  # fmt: skip
    assert main([*argv, str(tmp_path / "whole")]) == 0
    drive = windows._episode_windows
    ctrl_c_at(monkeypatch, windows, "_episode_windows", 3)
    out = tmp_path / "ds"
    assert main([*argv, str(out)]) == 130
    err = capsys.readouterr().err
    partial = tmp_path / ".ds.partial"
    assert f"recorded until the last checkpoint are kept in {partial}: the same command" in err
    # other arguments are refused, the interrupted recording kept
    assert main([*argv[:-1], "--seed", "3", "--out", str(out)]) == 2
    assert "holds an interrupted recording that was made with --seed 0 (now 3)" in (
        capsys.readouterr().err)  # fmt: skip
    assert (partial / "progress.json").is_file()
    assert not out.exists() and (partial / "progress.json").is_file()
    monkeypatch.setattr(windows, "_episode_windows", drive)
    assert main([*argv, str(out)]) == 0
    assert "going on with the interrupted recording" in capsys.readouterr().err
    assert not partial.exists() and not (out / "progress.json").exists()
    same = ("count", "shards", "scenarios")
    whole, part = (json.loads((d / "manifest.json").read_text()) for d in (tmp_path / "whole", out))
    assert {k: whole[k] for k in same} == {k: part[k] for k in same}


def test_record_counts_the_windows_of_episodes_that_end_early(tmp_path, monkeypatch, capsys):
    """An episode that ended before its reference (a collision, off the road) gave no more
    windows, and nothing said so. ``record`` says how many and why (manifest and summary),
    every window is either recorded or counted, and an interrupted recording goes on with
    the count. Reaching the destination ends no recorded episode: on US-101 (4_1) 5 of 17
    humans crawl within its 2 m of their end point for seconds (606 windows were recorded,
    167 not taken; now 663, the 92 of 2 episodes off the road not taken, nor 18 whose labels
    start behind the ego, which overshot a human's hard stop)."""
    from gridsim.envs.gridsim_env import GridSimEnv
    from neurotrajectory.data import recording, windows

    argv = ["record", "--scenario", "us101_4_1", "--quiet", "--out"]
    assert main([*argv, str(tmp_path / "whole")]) == 0
    out, err = capsys.readouterr()
    early = json.loads(out)["ended_early"]
    assert "destination reached" not in early["episodes"] and early["episodes"]["off road"] >= 1
    assert "episode(s) ended before their reference did (" in err
    # the episodes are named, to look them up: the track, how and when it ended
    assert len(early["first"]) == sum(early["episodes"].values())
    assert all(re.fullmatch(r"USA_US101-4_1_T-1/\d+: (off road|collision) at \d+\.\d s.*", e)
               for e in early["first"])  # fmt: skip
    assert f"they: {early['first'][0]}" in err
    whole = json.loads((tmp_path / "whole" / "manifest.json").read_text())
    assert whole["ended_early"] == whole["scenarios"][0]["ended_early"] == early
    # every window of every track's reference, recorded or counted as not taken
    plan, _ = windows.scenario_episodes("us101_4_1", 1, 0, None, None)
    possible = 0
    for episode in plan:
        env = GridSimEnv("us101_4_1", **episode.overrides)
        env.reset(seed=episode.seed)
        end, horizon = env.reference.end_time, env.cfg.env.setpoint_times[-1]
        possible += int(np.floor((end - horizon) / env.cfg.env.decision_period + 1e-6)) + 1
    assert whole["count"] + early["windows_not_taken"] + early["windows_behind"] == possible
    assert whole["count"] > 606  # (the windows before the destination no longer ended them)
    # interrupted after some episodes ended early: the count goes on
    monkeypatch.setattr(recording, "CHECKPOINT_SECONDS", 0.0)
    drive = windows._episode_windows
    ctrl_c_at(monkeypatch, windows, "_episode_windows", 12)
    assert main([*argv, str(tmp_path / "ds")]) == 130
    monkeypatch.setattr(windows, "_episode_windows", drive)
    assert main([*argv, str(tmp_path / "ds")]) == 0
    part = json.loads((tmp_path / "ds" / "manifest.json").read_text())
    assert part["ended_early"] == early and part["count"] == whole["count"]


def test_a_warm_start_interrupted_goes_on_from_its_batch(tmp_path, monkeypatch, capsys):
    """A warm start can fit for many minutes on a large dataset: a real Ctrl-C (SIGINT) inside
    a batch of the first epoch waits for the batch's end, keeps the fit as far as it got, and
    --resume goes on from there to the warm start of an unbroken run."""
    import os
    import signal

    import torch

    from neurotrajectory.evolve import warm_start

    argv = [*QUICK, "--pretrain-episodes", "2", "--pretrain-epochs", "3", "--heldout", "0"]
    assert main(["train", *argv, "--out", str(tmp_path / "whole")]) == 0
    inputs, batches, ctrl_c = warm_start.window_inputs, [], [3]

    def ctrl_c_in_third_batch(*args):  # (the fit's batches run with gradients, passes without)
        if torch.is_grad_enabled():
            batches.append(1)
            if len(batches) in ctrl_c:
                os.kill(os.getpid(), signal.SIGINT)
        return inputs(*args)

    monkeypatch.setattr(warm_start, "window_inputs", ctrl_c_in_third_batch)
    run = tmp_path / "run"
    assert main(["train", *argv, "--out", str(run)]) == 130
    assert "keeps its warm start's fit as far as it got; go on with: " \
        f"neurotrajectory train --resume {run}" in capsys.readouterr().err  # fmt: skip
    whole = json.loads((tmp_path / "whole" / "pretrain.json").read_text())
    per_epoch = -(-whole["windows"] // 32)  # batches of 32 windows
    saved = torch.load(run / "warm_start_fit.pt", weights_only=True)
    assert saved["batch"] > 0  # inside an epoch: the batch it arrived in, finished
    assert saved["epochs"] * per_epoch + saved["batch"] == 3
    batches.clear()
    ctrl_c.clear()
    assert main(["train", "--resume", str(run), "--quiet"]) == 0
    assert len(batches) == 3 * per_epoch - 3  # no batch fitted twice
    with np.load(tmp_path / "whole" / "warm_start.npz") as a, np.load(run / "warm_start.npz") as b:
        np.testing.assert_array_equal(a["genome"], b["genome"])
    assert json.loads((run / "pretrain.json").read_text()) == whole
    assert not (run / "warm_start_fit.pt").exists()


def test_the_front_of_an_extension_stopped_before_its_end_is_said_to_be_the_earlier(tmp_path):
    """train --resume RUN --generations N, stopped before its end, keeps the front chosen
    before; rollout, heldout and evaluate used it without a word (table2.md then named the
    run's N generations). Loading it warns, with the command that finishes the run."""
    from gridsim.errors import DataWarning
    from neurotrajectory.compare.front import load_front

    run = tmp_path / "run"
    Run.create(run, TrainConfig(generations=1, **TINY)).train(progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        load_front(run)  # a finished run: nothing said
    config = json.loads((run / "config.json").read_text())
    config["train"]["generations"] = 3  # what an extension stopped at generation 2 leaves
    (run / "config.json").write_text(json.dumps(config))
    with pytest.warns(DataWarning, match=r"chosen after generation 1, but the run is set to 3 "
                      r".*`neurotrajectory train --resume .*run` finishes"):  # fmt: skip
        load_front(run)


def test_an_extension_without_a_held_out_drive_removes_the_earlier_front_s_report(tmp_path, capsys):
    """--heldout 0 carried over to an extension left heldout.json naming a knee of the front
    before; it is removed, saying how to drive the new one. A resume that chose the same
    front again keeps it."""
    run = tmp_path / "run"
    flags = [*QUICK[:-1], "--heldout", "1", "--validation-episodes", "1"]
    assert main(["train", *flags, "--out", str(run)]) == 0
    report = (run / "heldout.json").read_bytes()
    assert main(["train", "--resume", str(run), "--heldout", "0"]) == 0  # the same front
    assert (run / "heldout.json").read_bytes() == report
    capsys.readouterr()
    assert main(["train", "--resume", str(run), "--generations", "2", "--heldout", "0"]) == 0
    assert not (run / "heldout.json").exists()
    assert f"removed {run / 'heldout.json'}: it was of the front before" in capsys.readouterr().err


def test_a_run_made_from_relative_paths_resumes_from_any_folder(tmp_path, monkeypatch):
    """train --scenario scen/s.yaml kept the path as typed: resumed from another folder, the
    run refused its own scenario as removed, and rollout and heldout did not find it. A new
    run keeps its files by absolute paths (built-in names as they are)."""
    from importlib import resources

    work = tmp_path / "work"
    (work / "scen").mkdir(parents=True)
    source = resources.files("gridsim").joinpath("data", "scenarios", "seamless.yaml")
    (work / "scen" / "s.yaml").write_text(source.read_text().replace("name: seamless",
                                                                     "name: mine"))  # fmt: skip
    monkeypatch.chdir(work)
    assert main(["train", *QUICK, "--scenario", "scen/s.yaml", "--heldout", "0",
                 "--out", "runs/r"]) == 0  # fmt: skip
    assert Run.open(work / "runs" / "r").config.scenario == str(work / "scen" / "s.yaml")
    monkeypatch.chdir(tmp_path)
    assert main(["train", "--resume", str(work / "runs" / "r"), "--generations", "2",
                 "--quiet"]) == 0  # fmt: skip


def test_record_says_the_files_it_skipped_in_its_summary(tmp_path, capsys):
    """A folder's file that gives no window was named in a warning on stderr only: the
    summary a script reads (stdout) said nothing of it (a probe lost 1,700 ego tracks of a
    scene with one bad sample that way)."""
    from importlib import resources

    scenes = tmp_path / "scenes"
    scenes.mkdir()
    source = resources.files("gridsim").joinpath("data", "scenarios", "us101_4_1.yaml")
    (scenes / "us101_4_1.yaml").write_text(source.read_text())
    (scenes / "bad.xml").write_text('<?xml version="1.0"?><commonRoad')  # cut short
    out = tmp_path / "ds"
    assert main(["record", "--scenario", str(scenes), "--out", str(out), "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["windows"] > 0 and summary["skipped"] == [str(scenes / "bad.xml")]


def test_record_refuses_a_dataset_whose_files_changed_while_recording(tmp_path, monkeypatch,
                                                                      capsys):  # fmt: skip
    """A file replaced while ``record`` ran gave windows of both its contents, with the old
    contents' digest in the manifest (a probe: a per-vehicle file completed mid-recording):
    the change is found at the end and the dataset refused, naming the file."""
    from importlib import resources

    from neurotrajectory.data import recording

    scenes = tmp_path / "scenes"
    scenes.mkdir()
    source = resources.files("gridsim").joinpath("data", "scenarios", "us101_4_1.yaml")
    scene = scenes / "us101_4_1.yaml"
    scene.write_text(source.read_text())
    record = recording.record_group_into

    def edited_meanwhile(*args, **kwargs):
        out = record(*args, **kwargs)
        scene.write_text(scene.read_text() + "# edited\n")
        return out

    monkeypatch.setattr(recording, "record_group_into", edited_meanwhile)
    out = tmp_path / "ds"
    assert main(["record", "--scenario", str(scenes), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"files changed while they were recorded (changed: {scene.resolve()})" in err
    assert not (out / "manifest.json").exists()
