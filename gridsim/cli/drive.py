"""``gridsim drive``: the lane-following ego in a scenario, recording occupancy grids."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from gridsim.cli.flags import quiet_flag, scenario_flag, seed_flag
from gridsim.errors import GridSimError, OutputError
from gridsim.outputs import (
    new_folder,
    new_folder_problem,
    rounded,
    summary_text,
    write_json,
    write_npz,
)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "drive", help="drive the lane-following ego; write grids and a top-down frame"
    )
    scenario_flag(p, default="seamless")
    p.add_argument("--seconds", type=float, default=20.0, help="simulated time [s] (default 20)")
    seed_flag(p)
    p.add_argument("--out", default="out/drive", help="output folder")
    quiet_flag(p)
    p.set_defaults(func=execute)


def execute(args: argparse.Namespace) -> int:
    summary = drive(args.scenario, args.seconds, args.seed, Path(args.out), progress=not args.quiet)
    if summary.get("cut_at_track_end"):
        print(f"gridsim: drove {summary['simulated_s']:g} s, not {args.seconds:g}: the recording "
              f"of ego track {summary['ego_track']} ends there (its traffic and map end with "
              "it)", file=sys.stderr)  # fmt: skip
    print(summary_text(rounded(summary)))
    return 0


def drive(scenario: str, seconds: float, seed: int, out: Path, progress: bool = True) -> dict:
    """Drive ``seconds`` of simulated time (on a recorded scene at most until its ego track's
    recording ends, as an episode does); write ``grids.npz`` (uint8 ``(T, H, W)`` grids and
    their times), a few colour grid PNGs (``grid_TICK.png``, named by their tick),
    ``topdown.png`` (last frame) and ``summary.json`` into ``out``. Returns the summary."""
    from gridsim.outputs import progress_bar
    from gridsim.scenario.build import build_sensor, build_world
    from gridsim.scenario.collection import load_collection, pick
    from gridsim.scenario.schema import MAX_DURATION, MAX_TICKS
    from gridsim.seeding import episode_seed
    from gridsim.world.scripted_drivers import LaneFollower

    if not 0 < seconds <= MAX_DURATION:
        raise GridSimError(f"--seconds must be in (0, {MAX_DURATION:g}] (an hour of simulated "
                           f"time at most), got {seconds}")  # fmt: skip
    problem = new_folder_problem(out)
    if problem:
        raise OutputError(f"--out {out}: {problem}")
    episode = episode_seed(seed)  # the episode of `gridsim run --seed SEED` and reset(seed=)
    sc = pick(load_collection(scenario), episode)  # of a folder or glob: drawn from the seed
    world = build_world(sc, episode)
    sensor = build_sensor(sc)
    # On recorded scenes drive at the human's mean speed; elsewhere near the speed limit.
    track = world.ego_track
    speed = float(track.speed.mean()) if track is not None else 0.9 * sc.config.ego.vehicle.v_max
    driver = LaneFollower(speed=speed)
    cut = track is not None and track.duration < seconds  # (past its end the scene is
    if cut:  # empty and the map may end)
        seconds = float(track.duration)
    steps = max(1, int(round(seconds / world.dt)))
    if steps > MAX_TICKS:
        raise GridSimError(f"--seconds {seconds:g} is {steps:,} ticks of {world.dt:g} s; at most "
                           f"{MAX_TICKS:,} (the grids are kept in memory)")  # fmt: skip
    grids = np.empty((steps, sensor.spec.rows, sensor.spec.cols), np.uint8)
    times = np.empty(steps)
    start = world.ego[:2].copy()
    distance, collisions, off_road = 0.0, 0, 0
    for k in progress_bar(range(steps), desc=f"drive {sc.name}", unit="tick", disable=not progress):
        prev = world.ego[:2].copy()
        result = world.tick(*driver(world))
        distance += float(np.hypot(*(world.ego[:2] - prev)))
        collisions += result.collided
        off_road += result.off_road
        grids[k] = sensor.observe(world)
        times[k] = round(world.time, 9)  # a sum of ticks, to the nanosecond (as info["time"])
    with new_folder(out) as partial:  # out appears whole
        return _write(partial, out, sc, seed, episode, world, grids, times, steps, start,
                      distance, collisions, off_road, cut)  # fmt: skip


def _write(partial, out, sc, seed, episode, world, grids, times, steps, start, distance,
           collisions, off_road, cut: bool) -> dict:  # fmt: skip
    """Write the drive's files into ``partial``, the folder that becomes ``out`` once they are
    all there; the summary (``seed``: the user's, ``episode``: the episode seed drawn from
    it; ``cut``: it stopped where its ego track's recording ends, before the time asked
    for)."""
    import cv2

    from gridsim.render.annotations import Caption, annotate
    from gridsim.render.grids import colourise
    from gridsim.render.topdown import TopDownRenderer

    write_npz(partial / "grids.npz", compressed=True, grids=grids, times=times)
    for k in np.linspace(0, steps - 1, min(steps, 5)).astype(int):
        # (grid k is the world after tick k + 1, at times[k]: named by that tick)
        cv2.imwrite(str(partial / f"grid_{k + 1:05d}.png"), colourise(grids[k])[:, :, ::-1])
    view = TopDownRenderer()
    spec = sc.config.sensor
    frame = view.render(world, grids[-1], grid_frame=(spec.cell_size, spec.orientation))
    caption = Caption(f"lane follower, {sc.name} (seed {seed})", world.time, float(world.ego[3]))
    annotate(frame, caption, view.scale, view.view.inset_size, setpoints=False,
             orientation=spec.orientation)  # (the drive draws no set-points)  # fmt: skip
    cv2.imwrite(str(partial / "topdown.png"), frame[:, :, ::-1])
    summary = {
        "scenario": sc.name,
        "seed": seed,
        "episode_seed": episode,
        "simulated_s": round(world.time, 3),
        "ticks": steps,
        "distance_m": round(distance, 2),
        "straight_line_m": round(float(np.hypot(*(world.ego[:2] - start))), 2),
        "ticks_in_collision": int(collisions),
        "ticks_off_road": int(off_road),
        "traffic_active": int(world.traffic.fleet.active.sum()),
        **(
            {
                "ego_track": world.ego_track.track_id,
                "ego_track_s": round(float(world.ego_track.duration), 3),
                "cut_at_track_end": cut,
            }
            if world.ego_track is not None
            else {}
        ),  # fmt: skip
        "out": str(Path(out).absolute()),  # the folder of the outputs (once renamed)
        "outputs": sorted(
            [p.name for p in partial.iterdir() if not p.name.startswith(".")] + ["summary.json"]
        ),  # (this file, written next)
    }
    write_json(partial / "summary.json", summary, indent=2)
    return summary
