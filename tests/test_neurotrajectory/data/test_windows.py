"""Recording windows on recorded scenes: memory that does not grow with the tracks, and one
warning for the tracks a random ego is not drawn from."""

import gc
import warnings
import weakref

from gridsim.errors import DataWarning
from neurotrajectory.data import windows
from neurotrajectory.data.windows import drive_windows, scenario_episodes


def test_one_environment_at_a_time_while_recording_a_scene_track_by_track(monkeypatch):
    """Each ego track is its own environment, holding the whole scene's traffic: the one
    before is let go when the next is built (all were kept, memory grew with the tracks
    squared: 18 GB for 1,000 vehicles)."""
    made: list[weakref.ref] = []
    alive_at_build: list[int] = []

    class Counted(windows.GridSimEnv):
        def __init__(self, *args, **kwargs):
            gc.collect()
            alive_at_build.append(sum(r() is not None for r in made))
            super().__init__(*args, **kwargs)
            made.append(weakref.ref(self))

    monkeypatch.setattr(windows, "GridSimEnv", Counted)
    planned, _ = scenario_episodes("us101_3_3")
    found = drive_windows("us101_3_3", planned[:4], stride=10)
    assert len(made) == 4 and alive_at_build == [0, 0, 0, 0]
    assert len(set(found.track.tolist())) == 4


def test_tracks_a_random_ego_is_not_drawn_from_are_named_once():
    """``record`` drives every track that lasts the horizon, trucks too: one warning names
    them all (each environment warned of its own, one line per track)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        planned, _ = scenario_episodes("us101_3_3")
        mine = [p for p in planned if p.track.rsplit("/", 1)[1] in ("387", "401", "388")]
        drive_windows("us101_3_3", mine, stride=10)
    said = [str(w.message) for w in caught if issubclass(w.category, DataWarning)]
    assert len(said) == 1, said
    assert "2 of the 12 tracks driven as the ego are not ones a random ego" in said[0]
    assert "387, 401;" in said[0]
