"""Output files and folders: checks before writing, and writes that never leave half a file."""

import csv
import json
import os
import re

import numpy as np
import pytest

from gridsim.outputs import (
    atomic_text,
    new_folder_problem,
    output_problem,
    read_manifest,
    write_json,
    write_npz,
    write_text,
)


def test_writes_round_trip_and_leave_no_temporary_files(tmp_path):
    write_json(tmp_path / "a.json", {"x": [1, 2.5]})
    write_text(tmp_path / "b.txt", "line\n")
    write_npz(tmp_path / "c.npz", compressed=True, g=np.arange(6).reshape(2, 3))
    with atomic_text(tmp_path / "d.csv") as fh:
        csv.writer(fh).writerow(["t", 0.1])
    assert json.loads((tmp_path / "a.json").read_text()) == {"x": [1, 2.5]}
    assert (tmp_path / "b.txt").read_text() == "line\n"
    with np.load(tmp_path / "c.npz") as f:
        np.testing.assert_array_equal(f["g"], np.arange(6).reshape(2, 3))
    assert (tmp_path / "d.csv").read_bytes() == b"t,0.1\r\n"  # csv line ends, untranslated
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.txt", "c.npz", "d.csv"]


def test_written_files_have_the_usual_permissions(tmp_path):
    old = os.umask(0o022)
    try:
        path = write_text(tmp_path / "new.txt", "a")
        assert path.stat().st_mode & 0o777 == 0o644  # not mkstemp's private 0600
        path.chmod(0o640)
        write_text(path, "b")  # a replaced file keeps its permissions
        assert path.stat().st_mode & 0o777 == 0o640 and path.read_text() == "b"
    finally:
        os.umask(old)


def test_a_failed_write_keeps_the_old_file_whole(tmp_path):
    path = write_text(tmp_path / "table.csv", "old\n")
    with pytest.raises(RuntimeError), atomic_text(path) as fh:
        fh.write("half a new tab")
        raise RuntimeError("interrupted")
    assert path.read_text() == "old\n"
    with pytest.raises(TypeError):
        write_json(path, {"not JSON": object()})
    assert path.read_text() == "old\n"
    assert [p.name for p in tmp_path.iterdir()] == ["table.csv"]  # no temporary file left


def test_new_folders_must_be_empty_and_the_message_says_what_to_do(tmp_path):
    assert new_folder_problem(tmp_path / "new") is None
    assert new_folder_problem(tmp_path) is None  # empty
    write_text(tmp_path / "x", "")
    assert new_folder_problem(tmp_path) == "exists and is not empty: choose another --out"
    assert new_folder_problem(tmp_path, hint="use --resume") == (
        "exists and is not empty: use --resume"
    )
    assert new_folder_problem(tmp_path / "x") == "is a file, expected a folder"


@pytest.mark.parametrize(
    ("content", "message"),
    [(None, "is not a thing (no m.json)"),
     ("{bad", "m.json: unreadable JSON (Expecting property name"),
     ("[1]", "m.json: expected an object with 'format' and 'items', got a list"),
     ('{"format": 2}', "m.json: expected an object with 'format' and 'items', got an object "
                       "without 'items'"),
     ('{"format": 3, "items": []}', "m.json: format 3, expected 2")],
)  # fmt: skip
def test_a_folders_manifest_is_checked_and_errors_name_the_file(tmp_path, content, message):
    if content is not None:
        write_text(tmp_path / "m.json", content)
    with pytest.raises(ValueError, match=re.escape(message)):
        read_manifest(tmp_path, "m.json", "thing", ValueError, (1, 2), keys=("items",))
    if content is None:
        return
    write_text(tmp_path / "m.json", '{"format": 1, "items": [3]}')  # an older format is read
    assert read_manifest(tmp_path, "m.json", "thing", ValueError, (1, 2), ("items",)) == {
        "format": 1, "items": [3]}  # fmt: skip


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
def test_a_folder_that_refuses_files_is_caught_before_any_work(tmp_path):
    """/proc passes a permission check, even for root, but takes no new file."""
    from pathlib import Path

    assert output_problem(Path("/proc/x.json"), directory=False).startswith("/proc is not writable")
    assert output_problem(Path("/proc/run"), directory=True).startswith("/proc is not writable")
    assert output_problem(tmp_path / "x.json", directory=False) is None
    assert list(tmp_path.iterdir()) == []  # the probe leaves nothing


def test_a_folder_that_may_not_be_searched_is_named(tmp_path, monkeypatch):
    """(as a user without x permission on a folder of the path sees it; root is not refused)"""
    from pathlib import Path

    def refused(self):
        raise PermissionError(13, "Permission denied", str(tmp_path / "locked"))

    monkeypatch.setattr(Path, "is_dir", refused)
    assert output_problem(tmp_path / "locked" / "x.json", directory=False) == (
        f"{tmp_path / 'locked'} is not accessible (Permission denied)"
    )


def test_progress_bars_in_a_log_are_redrawn_every_half_minute():
    """A bar whose stream is not a terminal (a log file, a pipe) redraws at most every
    LOG_INTERVAL seconds (a 2-minute train wrote 23 kB of redraws into a log); on a terminal
    as tqdm does."""
    import io

    from gridsim.outputs import LOG_INTERVAL, progress_bar

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    log, terminal = io.StringIO(), Terminal()
    with progress_bar(total=3, file=log) as bar, progress_bar(total=3, file=terminal) as live:
        assert bar.mininterval == LOG_INTERVAL == 30.0 and live.mininterval == 0.1
        for k in range(3):
            bar.update()
            live.update()
            bar.set_postfix(epoch=k)  # (a new postfix forced a redraw: a line per epoch)
            live.set_postfix(epoch=k)
    # a bar done within LOG_INTERVAL is not drawn in a log at all (a 10 s train's nested
    # per-epoch bars wrote 15.7 kB of them; 0.5 kB now); on a terminal it is, to the end
    assert log.getvalue() == "" and "3/3" in terminal.getvalue()
    assert bar.delay == LOG_INTERVAL and live.delay == 0


def test_progress_bars_in_a_log_write_a_line_per_redraw():
    """In a log, tqdm's redraws (a return to the line's start) made one long line, and a
    message printed after a redraw was glued to it: each redraw is now a line of its own."""
    import io

    from gridsim.outputs import progress_bar

    log = io.StringIO()
    with progress_bar(total=3, file=log, desc="record x", unit="episode", mininterval=0,
                      maxinterval=0, delay=0) as bar:  # fmt: skip
        for _ in range(3):
            bar.update()
        bar.refresh()
        log.write("neurotrajectory: copying ...\n")
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue() and len(lines) >= 4
    assert lines[0].startswith("record x:") and "0/3" in lines[0]
    assert "neurotrajectory: copying ..." in lines  # on a line of its own
    assert lines[-1].startswith("record x: 100%") and "3/3" in lines[-1]
    nested = io.StringIO()  # a bar below another moves the cursor (an escape): no such line
    with progress_bar(total=2, file=nested, desc="outer", mininterval=0, maxinterval=0,
                      delay=0) as outer:  # fmt: skip
        for _ in range(2):
            with progress_bar(total=2, file=nested, desc="inner", leave=False, position=1,
                              mininterval=0, maxinterval=0, delay=0) as inner:  # fmt: skip
                inner.update(2)
            outer.update()
    said = nested.getvalue().splitlines()
    assert "\x1b" not in nested.getvalue() and all(line.strip() for line in said)
    assert said[-1].startswith("outer: 100%")


def test_a_full_disk_names_the_file_it_was_writing(tmp_path):
    """A full disk while a file was written said only "No space left on device" (a write to
    an open file carries no name): the error names the file, and the old one stays."""
    import errno
    from pathlib import Path

    from gridsim.outputs import atomic_write, write_text

    path = write_text(tmp_path / "checkpoint.json", "old")

    def full(tmp: str) -> None:
        Path(tmp).write_text("half")
        raise OSError(errno.ENOSPC, "No space left on device")

    with pytest.raises(OSError) as err:
        atomic_write(path, full)
    assert err.value.errno == errno.ENOSPC and err.value.filename == str(path)
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == [path.name]

    def full_named(tmp: str) -> None:  # an error that names the hidden file: the path instead
        raise OSError(errno.ENOSPC, "No space left on device", tmp)

    with pytest.raises(OSError) as err:
        atomic_write(path, full_named)
    assert err.value.filename == str(path)


def test_an_atomic_write_is_synced_and_a_failed_sync_keeps_the_old_file(tmp_path, monkeypatch):
    """The file is synced before its rename and the folder after (a power cut left empty
    checkpoints); an I/O error of the file's sync keeps the old file, while a file system
    that cannot sync (EINVAL, Windows' EBADF) is no error."""
    import errno
    import os

    from gridsim import outputs

    synced, fail = [], {}

    def fsync(fd):
        synced.append(os.readlink(f"/proc/self/fd/{fd}"))
        if fail:
            raise OSError(fail["errno"], os.strerror(fail["errno"]))

    monkeypatch.setattr(outputs.os, "fsync", fsync)
    path = outputs.write_text(tmp_path / "a.json", "old")
    assert synced[0].startswith(str(tmp_path / ".a.json.")) and synced[1] == str(tmp_path)
    fail["errno"] = errno.EIO
    with pytest.raises(OSError, match="Input/output error"):
        outputs.write_text(path, "new")
    assert path.read_text() == "old" and len(list(tmp_path.iterdir())) == 1
    fail["errno"] = errno.EINVAL
    outputs.write_text(path, "new")
    assert path.read_text() == "new"


def test_summaries_print_paths_as_written_where_the_console_can(monkeypatch):
    """A path with ü printed as \\u00fc (a user copying it got that); where standard output
    cannot write it (an ASCII console) the summary is escaped instead of failing the command
    after its work is done."""
    import io
    import sys

    from gridsim.outputs import summary_text

    assert summary_text({"out": "runs/ü"}) == '{\n  "out": "runs/ü"\n}'
    monkeypatch.setattr(sys, "stdout", io.TextIOWrapper(io.BytesIO(), encoding="ascii"))
    assert summary_text({"out": "runs/ü"}) == '{\n  "out": "runs/\\u00fc"\n}'
