"""Headless video export with imageio: MP4 through imageio-ffmpeg, GIF as the fallback."""

from __future__ import annotations

import contextlib
import functools
import logging
import os
from collections.abc import Callable
from pathlib import Path

import imageio.v2 as imageio
import numpy as np

from gridsim.envs.episode import Episode, Policy, check_steps, run_episode
from gridsim.errors import GridSimError
from gridsim.outputs import output_problem

log = logging.getLogger(__name__)

VIDEO_SUFFIXES = (".mp4", ".gif")


def video_problem(path: str | Path) -> str | None:
    """Why a video cannot be written to ``path``, or None if it can (nothing is created)."""
    suffix = Path(path).suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        return f"unsupported extension {suffix or '(none)'!r}; use .mp4 or .gif"
    return output_problem(path, directory=False)


class VideoWriter:
    """Writes RGB frames ``(H, W, 3)`` uint8 to ``path`` at ``fps`` frames per second.

    ``.mp4`` is encoded with H.264 by imageio-ffmpeg; if that is not available the frames go to
    a ``.gif`` beside it instead (:attr:`path` tells which). ``.gif`` is written directly.
    Frames go to a hidden file beside :attr:`path` that :meth:`close` renames to it: a video
    stopped half-way (an error, Ctrl-C: leaving the ``with`` block by an exception, or
    :meth:`abort`) leaves no file and an earlier one at :attr:`path` as it was.
    """

    def __init__(self, path: str | Path, fps: float) -> None:
        self.path = Path(path)
        problem = video_problem(self.path)
        if problem:
            raise GridSimError(f"video {self.path}: {problem}")
        if not fps > 0:
            raise GridSimError(f"fps must be > 0, got {fps}")
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.fps = float(fps)
        self.frames = 0
        self._writer = None
        if self.path.suffix.lower() == ".mp4":
            self._partial = self._partial_of(self.path)
            try:
                self._writer = imageio.get_writer(
                    self._partial, fps=self.fps, codec="libx264", macro_block_size=1,
                    ffmpeg_log_level="error", pixelformat="yuv420p",
                )  # fmt: skip
            except Exception as exc:  # no ffmpeg backend: fall back to GIF
                log.warning("MP4 export unavailable (%s); writing a GIF instead",
                            str(exc).replace(str(self._partial), str(self.path)))  # fmt: skip
                self.path = self.path.with_suffix(".gif")
        if self._writer is None:
            self._partial = self._partial_of(self.path)
            self._writer = imageio.get_writer(
                self._partial, mode="I", duration=1000.0 / self.fps, loop=0
            )

    @staticmethod
    def _partial_of(path: Path) -> Path:
        """Where the frames of ``path`` are written until :meth:`close` (same folder and
        suffix, so that the same writer takes it and the rename stays on one file system)."""
        return path.with_name(f".{path.stem}.partial{path.suffix}")

    def write(self, frame: np.ndarray) -> None:
        """Append ``frame`` uint8 ``(H, W, 3)``, of the size of the first. H.264 (``.mp4``)
        takes even sizes only: an odd height or width gets its last row or column again."""
        frame = np.asarray(frame)
        if frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
            raise GridSimError(f"frames must be uint8 (H, W, 3), got {frame.dtype} {frame.shape}")
        if self.frames == 0:
            self._size = frame.shape[:2]
        elif frame.shape[:2] != self._size:
            raise GridSimError(f"video {self.path}: frame {self.frames} is {frame.shape[0]} x "
                               f"{frame.shape[1]} pixels, the video's are {self._size[0]} x "
                               f"{self._size[1]} (a video's frames have one size)")  # fmt: skip
        if self.path.suffix.lower() == ".mp4" and (frame.shape[0] % 2 or frame.shape[1] % 2):
            frame = np.pad(frame, ((0, frame.shape[0] % 2), (0, frame.shape[1] % 2), (0, 0)),
                           mode="edge")  # fmt: skip
        self._writer.append_data(frame)
        self.frames += 1

    def close(self) -> None:
        """Finish the video and put it at :attr:`path` (replacing any file there); if the
        encoder fails to finish, nothing is left and the error is raised."""
        if self._writer is not None:
            writer, self._writer = self._writer, None
            try:
                writer.close()
            except BaseException:
                _drop(writer)
                self._partial.unlink(missing_ok=True)
                raise
            if not self._partial.exists():  # (a writer given no frame may write no file)
                return
            if self.frames and (problem := _unfinished(self._partial)):
                # (ffmpeg says its error on stderr and exits; the writer does not raise)
                self._partial.unlink(missing_ok=True)
                raise GridSimError(f"video {self.path}: {problem}; nothing was written (a file "
                                   "there before is left as it was): free some space, or "
                                   "write the video elsewhere")  # fmt: skip
            os.replace(self._partial, self.path)

    def abort(self) -> None:
        """Stop without a video: the frames so far are deleted, :attr:`path` left as it was
        (while another error is on its way: an encoder that fails to stop too is not
        reported over it)."""
        if self._writer is not None:
            writer, self._writer = self._writer, None
            try:
                with contextlib.suppress(Exception):
                    writer.close()
            finally:
                self._partial.unlink(missing_ok=True)

    def __enter__(self) -> VideoWriter:
        return self

    def __exit__(self, kind, *exc) -> None:
        if kind is None:
            self.close()
        else:
            self.abort()


def record_episode(
    env,
    policy: Policy,
    path: str | Path | None,
    steps: int | None = None,
    seed: int | None = None,
    on_step: Callable[[object, dict], None] | None = None,
    overlay: bool = True,
    label: str | Callable[[object], str] | None = None,
) -> tuple[Episode, Path | None]:
    """:func:`~gridsim.envs.episode.run_episode`, filmed: with a ``path``, the env must be
    made with ``render_mode="rgb_array"``; one frame per step (plus the first) is written at
    the environment's real rate, with ``overlay`` (the default) annotated
    (:mod:`gridsim.render.annotations`: ``label`` for the driver, by default the policy's
    name (:func:`policy_name`) and the episode's (:func:`episode_name`; its episode seed
    when ``seed`` is None), or ``label(env)`` (e.g. to name the scene a collection drew),
    time, speed, the fitness so far, how the episode ended, a colour legend, a scale bar);
    ``on_step(env, info)`` after every step. Returns the episode and the video's path
    (``None`` without one)."""
    check_steps(steps)
    if label is None:  # the driver and the episode, so that it can be driven again
        name = policy_name(policy)

        def label(env) -> str:
            said = episode_name(env, seed)
            if seed is None:  # (reset(options={"episode_seed": ...}) drives it again)
                said += f", episode seed {env.unwrapped.episode_seed}"
            return f"{name}, {said}"

    if path is not None and getattr(env, "render_mode", None) != "rgb_array":
        raise GridSimError("a video needs an environment made with render_mode='rgb_array'")
    fitness = np.zeros(3)
    with contextlib.ExitStack() as stack:
        video = None
        if path is not None:
            video = stack.enter_context(VideoWriter(path, env.metadata.get("render_fps", 10)))

        taken = [0]  # steps of this episode

        def film(env, info: dict) -> None:
            if video is not None:
                name = label(env) if callable(label) else label
                stopped = steps is not None and taken[0] == steps
                video.write(_frame(env, info, overlay, name, fitness.copy(), stopped))

        def start(env, info: dict) -> None:
            fitness[:], taken[0] = 0.0, 0
            film(env, info)

        def observe(env, info: dict) -> None:
            fitness[:] += (info["l1"], info["l2"], info["l3"])
            taken[0] += 1
            film(env, info)
            if on_step is not None:
                on_step(env, info)

        episode = run_episode(env, policy, steps, seed, on_step=observe, on_reset=start)
    return episode, (video.path if video is not None else None)


def record_rollout(
    env,
    policy: Policy,
    path: str | Path | None,
    steps: int | None,
    seed: int | None = None,
    on_step: Callable[[dict], None] | None = None,
    overlay: bool = True,
    label: str | None = None,
) -> tuple[Path | None, list[dict]]:
    """Run ``policy(env, obs, info) -> action`` for up to ``steps`` steps of one episode
    (None: until it ends), filmed as :func:`record_episode` films it; ``on_step(info)`` after
    every step. Returns the video path (``None`` without one) and the infos of all steps,
    each with its ``"reward"``."""
    observe = None if on_step is None else (lambda env, info: on_step(info))
    episode, video = record_episode(env, policy, path, steps, seed, observe, overlay, label)
    return video, episode.infos


def policy_name(policy: Policy) -> str:
    """What a video calls the driver ``policy``: a function's or method's name, else its
    class's; a ``functools.partial`` its function's; "a lambda policy" for a lambda."""
    if isinstance(policy, functools.partial):
        return policy_name(policy.func)
    name = getattr(policy, "__name__", None) or type(policy).__name__
    return "a lambda policy" if name == "<lambda>" else name


def _unfinished(path: Path) -> str | None:
    """Why the video file ``path`` that its encoder closed without an error cannot be played
    (an MP4 without its index, the ``moov`` box ffmpeg writes last: a disk that filled up; a GIF
    without its trailer), or None."""
    with path.open("rb") as fh:
        if path.suffix.lower() == ".gif":
            fh.seek(0, os.SEEK_END)
            if fh.tell() == 0:
                return "the encoder wrote an empty file (a disk full?)"
            fh.seek(-1, os.SEEK_END)
            return None if fh.read(1) == b"\x3b" else "the GIF is cut short (a disk full?)"
        end = fh.seek(0, os.SEEK_END)
        at, whole = 0, set()  # the top-level boxes that end within the file
        while at + 8 <= end:  # a box: size (4 bytes, big-endian), type (4), [64-bit size]
            fh.seek(at)
            head = fh.read(16)
            size, kind = int.from_bytes(head[:4], "big"), head[4:8]
            if size == 1:
                size = int.from_bytes(head[8:16], "big")
            elif size == 0:  # to the end of the file
                size = end - at
            if size < 8 or at + size > end:  # not a box, or one cut short
                break
            whole.add(kind)
            at += size
    if b"moov" not in whole or at != end:
        return (
            "the encoder did not finish the MP4 file (its index missing or cut short: a disk full?)"
        )
    return None


def _drop(writer) -> None:
    """An imageio writer whose close failed, let go: its buffered frames (a GIF's, all of
    them) dropped, so that its finaliser does not try to write them again (a traceback per
    try, after the error was said)."""
    instance = getattr(writer, "instance", None)
    pending = getattr(instance, "images_to_write", None)
    if isinstance(pending, list):
        pending.clear()
    with contextlib.suppress(Exception):
        writer.close()
    with contextlib.suppress(Exception):
        writer.closed = True


def episode_name(env, seed: int | None) -> str:
    """What a frame calls the episode of ``env`` (after its reset), so that it can be driven
    again: the scene (a collection's drawn one), the recorded track the ego drives (on a
    recorded scene) and the ``seed``, e.g. ``"us101_4_1, track 395, seed 0"``."""
    u = env.unwrapped
    parts = [u.scenario.name]
    track = u.world.ego_track if u.world is not None else None
    if track is not None:
        parts.append(f"track {track.track_id}")
    if seed is not None:
        parts.append(f"seed {seed}")
    return ", ".join(parts)


def _frame(env, info: dict, overlay: bool, label: str | None, fitness: np.ndarray,
           stopped: bool = False) -> np.ndarray:  # fmt: skip
    """``env.render()``, annotated if ``overlay`` (see :func:`record_episode`; ``stopped``: the
    episode's last step, at the caller's steps limit)."""
    from gridsim.render.annotations import annotate_env_frame

    frame = env.render()
    return annotate_env_frame(env, frame, info, label, fitness, stopped) if overlay else frame
