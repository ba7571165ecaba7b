"""Scenario YAML: loading by name and path, precise errors, overrides, fuzzing."""

import string
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from gridsim.cli import main
from gridsim.errors import ScenarioError
from gridsim.scenario.build import build_world
from gridsim.scenario.families.inner_city import CityRoadConfig
from gridsim.scenario.families.seamless import SeamlessRoadConfig
from gridsim.scenario.loader import (
    absolute_paths,
    builtin_scenarios,
    deep_merge,
    load_scenario,
    parse_scenario,
)


def test_builtins_are_listed_with_descriptions():
    names = builtin_scenarios()
    assert {
        "seamless",
        "inner_city",
        "us101_3_3",
        "us101_4_1",
        "lankershim_1_1",
        "peachtree_4_8",
    } <= set(names)
    assert all(desc for desc in names.values())


def test_table_one_parameters():
    seamless = load_scenario("seamless").config
    city = load_scenario("inner_city").config
    assert isinstance(seamless.road, SeamlessRoadConfig) and isinstance(city.road, CityRoadConfig)
    assert (seamless.traffic.participants, city.traffic.participants) == (10, 20)
    assert (seamless.traffic.v_max, city.traffic.v_max) == (13.88, 8.33)
    assert (seamless.traffic.v_min, city.traffic.v_min) == (4.16, 2.77)
    assert seamless.traffic.a_max == city.traffic.a_max == 2.0
    assert seamless.road.straight_fraction == 0.6 and seamless.road.mean_curve_angle_deg == 55


def test_load_by_path_and_relative_files(tmp_path):
    csv = tmp_path / "my_tracks.csv"
    csv.write_text(
        "scenario_id,track_id,time_s,x_m,y_m,heading_rad,speed_mps,length_m,width_m\n"
        + "\n".join(f"a,1,{k * 0.1:.1f},{k:.1f},0,0,10,4.5,1.8" for k in range(40))
        + "\n"
    )
    doc = yaml.safe_load(open_builtin("seamless"))
    doc["traffic"] = {"library": ["my_tracks.csv"]}
    path = tmp_path / "mine.yaml"
    path.write_text(yaml.safe_dump(doc))
    sc = load_scenario(path)
    world = build_world(sc, seed=0)
    assert world.traffic.fleet.active.sum() > 0
    assert sc.source == str(path)


def open_builtin(name):
    from importlib import resources

    return (resources.files("gridsim") / "data" / "scenarios" / f"{name}.yaml").read_text()


def test_unknown_name_lists_the_builtins():
    with pytest.raises(ScenarioError, match=r"unknown scenario 'sea'.*seamless"):
        load_scenario("sea")
    with pytest.raises(ScenarioError, match=r"unknown scenario 'seamles' \(did you mean "
                       r"'seamless'\?\); built-in scenarios: inner_city, "):  # fmt: skip
        load_scenario("seamles")


def test_missing_file(tmp_path, monkeypatch):
    """A relative path says where it was looked for (the working folder may not be the one
    the user thinks)."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ScenarioError) as err:
        load_scenario("nowhere/x.yaml")
    wanted = (
        f"scenario file not found: nowhere/x.yaml (looked for as {tmp_path / 'nowhere/x.yaml'})"
    )
    assert str(err.value) == wanted


def test_a_number_with_leading_zeros_is_kept_as_written(tmp_path):
    """YAML 1.1 reads ``00427`` as octal 279: a zero-padded track id became an id never
    written (a probe: "not in scene: 279"). It is kept as text; a number key given so says
    to drop the zeros."""
    from gridsim.scenario.loader import _load_yaml

    doc = _load_yaml("a: 00427\nb: 0x1F\nc: 12\nd: 0\ne: -007\nf: [0401, 381]\n", "x")
    assert doc == {"a": "00427", "b": 31, "c": 12, "d": 0, "e": "-007", "f": ["0401", 381]}
    padded = tmp_path / "padded.yaml"
    padded.write_text("name: p\nroad: {type: seamless}\nsimulation: {duration: 010}\n")
    said = r"duration: expects a number, not text: write it without the leading zeros"
    with pytest.raises(ScenarioError, match=said):
        load_scenario(padded)
    track = tmp_path / "track.yaml"
    track.write_text("name: t\nroad: {type: recorded, map: 'builtin:USA_US101-3_3_T-1', "
                     "scene: USA_US101-3_3_T-1}\nego: {track: [0401]}\n")  # fmt: skip
    with pytest.raises(ScenarioError, match=r"not in scene.*: 0401"):  # as written, not 257
        build_world(load_scenario(track))


def test_malformed_yaml_names_file_and_line(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text("name: x\nroad:\n  type: seamless\n  lanes: [3\n")
    with pytest.raises(ScenarioError, match=r"bad.yaml: malformed YAML at line \d+, column \d+"):
        load_scenario(p)


@pytest.mark.parametrize(
    ("patch", "message"),
    [
        ({"road": {"type": "seamless", "lanez": 3}}, r"road\.lanez: unknown key"),
        (
            {"road": {"type": "seamless", "lanes": "three"}},
            r"road\.lanes: Input should be a valid integer",
        ),
        # values pydantic would quietly convert
        (
            {"road": {"type": "seamless", "lanes": True}},
            r"road\.lanes: expects a number, not a YAML yes/no/true/false, which is a boolean "
            r"\(got True\)",
        ),
        (
            {"traffic": {"participants": "12"}},
            r"traffic\.participants: expects a number, not text: write it without quotes "
            r"\(got '12'\)",
        ),
        ({"simulation": {"duration": "10"}}, r"simulation\.duration: expects a number, not text"),
        # a number out of range is shown with its unit (100 ms for dt, per cent for a share)
        (
            {"simulation": {"dt": 100}},
            r"simulation\.dt: .* equal to 1 \(got 100\); simulation time step \[s\]",
        ),
        ({"road": {"type": "seamless", "lane_width": 350}}, r"\(got 350\); unit: m$"),
        ({"road": {"type": "seamless", "straight_fraction": 60}}, r"0-1 \(not per cent\)"),
        ({"sensor": {"mounts": [{"x": 100}]}}, r"sensor\.mounts\.0\.x: .*; unit: m$"),
        # a description that is more than a unit is shown whole (not "unit: behind, ahead] ...")
        (
            {"traffic": {"window": [10, 160]}},
            r"traffic\.window\.0: .* \(got 10\); \[behind, ahead\] metres of road",
        ),
        # a list one value short is said so, with what its values are ("window.1 is missing")
        (
            {"traffic": {"window": [160]}},
            r"traffic\.window: too few values \(no item 2\); \[behind, ahead\] metres",
        ),
        # items of a list of numbers too ('80' was 80 m, yes a 1 m curve radius)
        ({"traffic": {"window": ["80", 160]}}, r"traffic\.window\.0: expects a number, not text"),
        (
            {"road": {"type": "seamless", "curve_radius": [True, 50]}},
            r"road\.curve_radius\.0: expects a number, not a YAML yes/no",
        ),
        # an optional constrained number (Seed | None) too: 'yes' was seed 1
        ({"road": {"type": "seamless", "seed": True}}, r"road\.seed: expects a number, not a YAML"),
        (
            {"road": {"type": "seamless", "lanes": 12}},
            r"road\.lanes: Input should be less than or equal to 8 \(got 12\)",
        ),
        (
            {"road": {"type": "motorway"}},
            r"road.type 'motorway' is no scenario family; the families: inner_city, ",
        ),
        ({"sensor": {"rows": -128}}, r"sensor\.rows: Input should be greater than or equal to 8"),
        ({"sensor": {"cell_size": 0}}, r"sensor\.cell_size: Input should be greater than 0"),
        (
            {"traffic": {"v_min": 20, "v_max": 10}},
            r"traffic: v_max \(10\.0\) must be >= v_min",
        ),
        ({"simulation": {"dt": float("nan")}}, r"simulation\.dt"),
        ({"ego": {"lane": 5}}, r"ego\.lane \(5\) must be < road\.lanes \(3\)"),
        ({"extra": 1}, r"extra: unknown key"),
    ],
)
def test_validation_errors_name_the_key_path(patch, message):
    doc = yaml.safe_load(open_builtin("seamless"))
    with pytest.raises(ScenarioError, match=message) as err:
        parse_scenario(doc, "mine.yaml", overrides=patch)
    assert str(err.value).startswith("mine.yaml: invalid scenario")
    # the problem is said to be the keyword overrides' (it blamed the file alone); the same
    # in the file is the file's
    assert "\n  - (keyword override) " in str(err.value)
    with pytest.raises(ScenarioError, match=message) as err:
        parse_scenario(deep_merge(doc, patch), "mine.yaml")
    assert "keyword override" not in str(err.value)
    # an override the problem is not about is not named (a trainer's own overrides)
    with pytest.raises(ScenarioError, match=message) as err:
        parse_scenario(deep_merge(doc, patch), "mine.yaml", overrides={"env": {"history": 5}})
    assert "keyword override" not in str(err.value)


def test_overrides_are_merged_and_validated():
    sc = load_scenario("seamless", {"traffic": {"participants": 3}, "sensor": {"rows": 64}})
    assert sc.config.traffic.participants == 3 and sc.config.sensor.rows == 64
    assert sc.config.sensor.cols == 128  # untouched keys keep their values
    with pytest.raises(ScenarioError, match="traffic.participant: unknown key"):
        load_scenario("seamless", {"traffic": {"participant": 3}})


def test_timings_a_car_cannot_follow_are_warned_about():
    """Set-points closer than a tick, or decisions that outlast the first set-point, passed
    validation: fed the human's set-points, the car fell 11 m behind while l1 (which scores
    the plan) stayed 0."""
    from gridsim.errors import DataWarning
    from gridsim.scenario.loader import load_scenario

    with pytest.warns(DataWarning, match=r"env.setpoint_period 0.05 s is shorter than a tick"):
        load_scenario("seamless", {"env": {"setpoint_period": 0.05}})
    with pytest.warns(DataWarning, match=r"a decision \(env.decision_period 1 s\) outlasts the "
                      r"first set-point \(env.setpoint_period 0.5 s\)"):  # fmt: skip
        load_scenario("seamless", {"env": {"decision_period": 1.0}})
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        load_scenario("seamless", {"env": {"decision_period": 0.5}})  # (one set-point: fine)


def test_track_ids_saved_as_floats_are_named_as_such():
    """A track file whose id column a spreadsheet saved as floats ("381.0"): ego.track 381
    was "not in scene" beside a list of 381.0, 383.0, ... with no word why."""
    from types import SimpleNamespace

    from gridsim.scenario.families.recorded import checked_ego_tracks

    scenario = SimpleNamespace(source="x.yaml")
    tracks = [SimpleNamespace(track_id=f"{i}.0") for i in (373, 381, 383)]
    hint = "(the file's ids are floats: '381' is there as '381.0'; write its id column as"
    for wanted in ("381", ["381", "383"]):
        with pytest.raises(ScenarioError) as info:
            checked_ego_tracks(scenario, tracks, wanted, "scene")
        assert hint in str(info.value)
    with pytest.raises(ScenarioError) as info:
        checked_ego_tracks(scenario, tracks, "999", "scene")
    assert "floats" not in str(info.value)


def test_bad_references_are_reported(tmp_path):
    doc = yaml.safe_load(open_builtin("us101_3_3"))
    doc["road"]["map"] = "builtin:USA_nowhere"
    with pytest.raises(ScenarioError, match=r"road.map 'builtin:USA_nowhere': no such built-in "
                                            r"file \(they are named without .xml\): "
                                            r"builtin:USA_Lanker-1_1_T-1, "):  # fmt: skip
        build_world(parse_scenario(doc, "x.yaml"), 0)
    doc = yaml.safe_load(open_builtin("us101_3_3"))
    doc["ego"] = {"track": "999999"}
    with pytest.raises(ScenarioError, match="ego.track '999999' is not in scene"):
        build_world(parse_scenario(doc, "x.yaml"), 0)
    doc = yaml.safe_load(open_builtin("seamless"))
    doc["traffic"] = {"library": ["missing.csv"]}
    with pytest.raises(ScenarioError, match="traffic.library: file not found: 'missing.csv'"):
        build_world(parse_scenario(doc, "x.yaml", base_dir=tmp_path), 0)
    doc = yaml.safe_load(open_builtin("us101_3_3"))
    doc["road"]["map"] = "USA_US101-3_3_T-1"  # a built-in's name without its prefix
    with pytest.raises(ScenarioError, match=r"road.map: file not found: .* did you mean "
                                            r"'builtin:USA_US101-3_3_T-1'\?"):  # fmt: skip
        build_world(parse_scenario(doc, "x.yaml", base_dir=tmp_path), 0)


def test_validate_command(tmp_path, capsys):
    assert main(["validate", "scenarios/seamless.yaml"]) == 0
    assert "OK" in capsys.readouterr().out
    p = tmp_path / "bad.yaml"
    p.write_text("name: bad\nroad: {type: seamless, lanes: 0}\n")
    assert main(["validate", str(p)]) == 2
    err = capsys.readouterr().err
    assert "road.lanes: Input should be greater than or equal to 1 (got 0)" in err


def _leaves(doc: dict, path: tuple = ()):
    for key, value in doc.items():
        if isinstance(value, dict):
            yield from _leaves(value, (*path, key))
        else:
            yield (*path, key)


def _without(doc: dict, path: tuple) -> dict:
    out = {k: (_without(v, path[1:]) if k == path[0] and len(path) > 1 else v)
           for k, v in doc.items() if not (k == path[0] and len(path) == 1)}  # fmt: skip
    return out


@pytest.mark.parametrize("name", sorted(builtin_scenarios()))
def test_builtin_files_state_only_what_differs_from_their_family(name, tmp_path, capsys):
    """Every key a built-in file gives changes the scenario (the rest is its family's
    default, in one place); ``validate --resolved`` prints the scenario as it is run, and
    that YAML loads as the same scenario."""
    path = f"scenarios/{name}.yaml"
    doc = yaml.safe_load(Path(path).read_text())
    config = load_scenario(path).config
    for leaf in _leaves(doc):
        if leaf in (("name",), ("description",), ("road", "type")):
            continue
        try:
            without = parse_scenario(_without(doc, leaf), path, base_dir=tmp_path).config
        except ScenarioError:  # a key the family requires
            continue
        assert without != config, f"{path}: {'.'.join(leaf)} states its family's default"
    assert main(["validate", "--resolved", path]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"# {path}: OK") and f"# {path} as it is run" in out
    resolved = yaml.safe_load(out)  # the whole output: saved as a file, it loads
    assert set(resolved) >= {"simulation", "road", "traffic", "ego", "sensor", "env"}
    assert parse_scenario(resolved, path, base_dir=tmp_path).config == config


def test_a_resolved_scenario_saved_elsewhere_names_the_same_files(tmp_path, capsys):
    """`validate --resolved` names a scenario's files by absolute paths: saved in another
    folder, the output loads as the same scenario (a relative library had named a file
    beside the saved copy)."""
    from scenes import track, write_scene

    x = np.linspace(20.0, 60.0, 41)
    path = write_scene(tmp_path, [track("ego", x, np.full(41, -1.75))],
                       traffic={"library": "tracks.csv"})  # fmt: skip
    assert main(["validate", "--resolved", str(path)]) == 0
    (tmp_path / "other").mkdir()
    saved = tmp_path / "other" / "resolved.yaml"
    saved.write_text(capsys.readouterr().out)
    config = load_scenario(saved).config
    assert config.traffic.library == [str(tmp_path / "tracks.csv")]
    original = load_scenario(path)
    assert config.model_dump(mode="json") == absolute_paths(
        original.config.model_dump(mode="json"), original.base_dir
    )
    assert main(["validate", str(saved)]) == 0


def test_validate_resolved_takes_one_file(capsys):
    assert main(["validate", "--resolved", "scenarios/"]) == 2
    assert "--resolved prints one scenario; scenarios/ is a folder" in capsys.readouterr().err


def test_scenarios_command(capsys):
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out
    assert out.count("\n") == len(builtin_scenarios()) and "inner_city" in out


# -- property-based: random and malformed documents only ever raise ScenarioError ------------

scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=12),
)
keys = st.sampled_from(
    [
        "name",
        "road",
        "type",
        "lanes",
        "traffic",
        "sensor",
        "rows",
        "cols",
        "ego",
        "simulation",
        "dt",
        "mounts",
        "seamless",
        "inner_city",
        "recorded",
        "map",
        "scene",
        "library",
        "participants",
        "curve_radius",
        "zzz",
    ]
)
documents = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(keys, inner, max_size=5)),
    max_leaves=25,
)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(documents)
def test_random_documents_only_raise_scenario_errors(doc):
    try:
        parse_scenario(doc, "fuzz.yaml")
    except ScenarioError as exc:
        assert str(exc).startswith("fuzz.yaml:")


def mutate(doc, path, value):
    node = doc
    for k in path[:-1]:
        node = node.setdefault(k, {})  # a section the file leaves to the defaults
    node[path[-1]] = value
    return doc


PATHS = [
    ("road", "lanes"),
    ("road", "curve_radius"),
    ("road", "type"),
    ("traffic", "participants"),
    ("traffic", "v_max"),
    ("sensor", "rows"),
    ("sensor", "cell_size"),
    ("simulation", "dt"),
    ("ego", "speed"),
    ("ego", "vehicle"),
    ("name",),
    ("sensor", "mounts"),
]


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(PATHS), scalars | st.lists(scalars, max_size=3))
def test_mutated_builtin_documents_only_raise_scenario_errors(path, value):
    doc = mutate(yaml.safe_load(open_builtin("seamless")), path, value)
    try:
        sc = parse_scenario(doc, "fuzz.yaml")
    except ScenarioError:
        return
    assert sc.config.name


@settings(max_examples=100, deadline=None)
@given(st.text(alphabet=string.printable, max_size=200))
def test_random_yaml_text_only_raises_scenario_errors(tmp_path_factory, text):
    p = tmp_path_factory.mktemp("y") / "doc.yaml"
    p.write_text(text)
    try:
        load_scenario(p)
    except ScenarioError as exc:
        assert str(p) in str(exc)


def test_duplicate_keys_are_refused_with_both_lines(tmp_path):
    p = tmp_path / "twice.yaml"
    p.write_text("name: twice\ntraffic:\n  participants: 3\nsimulation:\n  duration: 5\n"
                 "traffic:\n  participants: 4\n")  # fmt: skip
    with pytest.raises(ScenarioError) as info:
        load_scenario(p)
    assert "twice.yaml" in str(info.value)
    assert "duplicate key 'traffic' (first at line 2, again at line 6)" in str(info.value)
    p.write_text("name: twice\ntraffic:\n  participants: 3\n  participants: 4\n")
    with pytest.raises(ScenarioError, match=r"duplicate key 'participants' \(first at line 3, "
                                            r"again at line 4\)"):  # fmt: skip
        load_scenario(p)


@pytest.mark.parametrize(
    "patch, message",
    [
        ({"ego": {"speed": 1e9}}, "ego.speed (1000000000.0) must be <= ego.vehicle.v_max (13.88)"),
        ({"simulation": {"dt": 1e-9}}, "simulation.dt: Input should be greater than or equal "
                                       "to 0.001"),
        ({"simulation": {"dt": 0.002, "duration": 600}},
         "duration / dt = 600 / 0.002 = 300000 ticks, more than 100000"),
        # km/h for m/s: traffic faster than any, and an l3 that would never count
        ({"traffic": {"v_min": 60, "v_max": 100}},
         "traffic.v_max (100 m/s) is faster than road traffic drives (at most 70 m/s, 252 "
         "km/h); speeds are in m/s (km/h / 3.6)"),
        ({"traffic": {"v_min": 60, "v_max": 100}},
         "traffic.v_min and v_max (env.speed_range's default) [60, 100] m/s begin above "
         "ego.vehicle.v_max (13.88 m/s): l3 would never count the ego's speed; give "
         "env.speed_range the speeds that count, in m/s"),
        ({"env": {"speed_range": [30, 50]}},
         "env.speed_range [30, 50] m/s begin above ego.vehicle.v_max (13.88 m/s)"),
        ({"simulation": {"duration": 0.05}},
         "simulation.duration (0.05 s) is shorter than one decision (env.decision_period, "
         "0.1 s)"),
        # radians where degrees are asked for
        ({"ego": {"vehicle": {"max_steer_deg": 0.6}}},
         "max_steer_deg 0.6 looks like radians (0.6 rad = 34.38 deg); it is in degrees"),
        ({"sensor": {"mounts": [{"fov_deg": 6.28}]}},
         "sensor.mounts.0: fov_deg 6.28 looks like radians (6.28 rad = 359.8 deg)"),
        # YAML's reading of a bare name
        ({"name": 101}, 'name: YAML reads this name as 101, not text: quote it (name: "...")'),
        ({"name": False}, "name: YAML reads this name as False, not text"),

    ],
)  # fmt: skip
def test_nonsense_speeds_and_time_steps_are_refused(patch, message):
    with pytest.raises(ScenarioError) as info:
        load_scenario("seamless", patch)
    assert message in str(info.value)


def test_a_check_across_keys_is_not_run_on_a_default_that_replaced_a_bad_value():
    """block_size 10 is refused; jitter's check against block_size / 4 then ran on the default
    block size and named its 11.25 as if it were the user's."""
    with pytest.raises(ScenarioError) as info:
        parse_scenario({"name": "x", "road": {"type": "inner_city", "block_size": 10,
                                              "jitter": 20}})  # fmt: skip
    assert "road.block_size: Input should be greater than or equal to 20 (got 10)" in str(
        info.value
    )
    assert "jitter" not in str(info.value)
    with pytest.raises(ScenarioError, match=r"jitter \(20.0\) must be < block_size / 4 \(12.5\)"):
        parse_scenario({"name": "x", "road": {"type": "inner_city", "block_size": 50,
                                              "jitter": 20}})  # fmt: skip


def test_a_city_larger_than_a_road_raster_holds_is_refused_by_its_keys():
    """The schema took 40 x 40 blocks of 500 m; the road then refused a raster of 9e8 cells
    naming neither the file nor the keys. A city that fits (20 x 20 blocks of 95 m, about
    2 km a side) is built."""
    big = {"name": "x", "road": {"type": "inner_city", "blocks_x": 30, "blocks_y": 30,
                                 "block_size": 200}}  # fmt: skip
    with pytest.raises(
        ScenarioError,
        match=r"big.yaml: invalid scenario \(1 problem\):\n  - road: blocks_x \(30\) and "
        r"blocks_y \(30\) blocks of block_size 200 m make a city of about "
        r"6.0 km x 6.0 km, more than a road's raster",
    ):
        parse_scenario(big, "big.yaml")
    fits = {**big, "road": {"type": "inner_city", "blocks_x": 20, "blocks_y": 20,
                            "block_size": 95, "jitter": 20, "lanes_per_direction": 4}}  # fmt: skip
    build_world(parse_scenario(fits, "fits.yaml"), 0)


def test_more_participants_than_fit_are_refused():
    sc = load_scenario("seamless", {"traffic": {"participants": 500}})
    with pytest.raises(ScenarioError) as info:
        build_world(sc, 0)
    assert "traffic.participants 500 is more than the " in str(info.value)
    assert "vehicles that fit in traffic.window [80, 160] m on 3 lane(s)" in str(info.value)
    capacity = int(str(info.value).split("more than the ")[1].split()[0])
    full = load_scenario("seamless", {"traffic": {"participants": capacity}})
    for seed in range(4):
        assert build_world(full, seed).traffic.fleet.active.sum() == capacity


def test_validate_suggests_the_key_meant(tmp_path, capsys):
    p = tmp_path / "typo.yaml"
    p.write_text("name: typo\nroad:\n  type: seamless\n  lane_widht: 3.2\n")
    assert main(["validate", str(p)]) == 2
    assert "road.lane_widht: unknown key (did you mean 'road.lane_width'?) (got 3.2)" in (
        capsys.readouterr().err
    )
    with pytest.raises(ScenarioError, match=r"participants: unknown key \(did you mean "
                                            r"'traffic.participants'\?\)"):  # fmt: skip
        load_scenario("seamless", {"participants": 5})
    # a key of another road type (it suggested itself: did you mean 'road.lanes'?)
    with pytest.raises(ScenarioError) as info:
        load_scenario("inner_city", {"road": {"lanes": 2}})
    assert ("road.lanes: unknown key for road type 'inner_city' (a key of 'seamless'); did "
            "you mean 'road.lanes_per_direction'? (got 2)") in str(info.value)  # fmt: skip


BOMB = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{n}: &{n} [{', '.join([f'*{p}'] * 9)}]\n" for p, n in zip("abcdefgh", "bcdefghi", strict=True)
)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (BOMB, "490,329,064 values once its aliases are expanded; at most 100,000"),
        ("a: " + "[" * 5000 + "]" * 5000, "brackets nested 5000 levels deep; at most 50"),
        ("a: &x [*x]\n", "a recursive alias"),
        ("".join(f"{' ' * k}k{k}:\n" for k in range(60)) + " " * 60 + "v: 1\n",
         "nested 62 levels deep; at most 50"),
        ("a: " + "x" * 1_000_001, "1,000,004 characters; a scenario file has at most 1,000,000"),
    ],
)  # fmt: skip
def test_hostile_yaml_is_refused_before_it_is_expanded(tmp_path, text, message):
    import tracemalloc

    p = tmp_path / "hostile.yaml"
    p.write_text(text)
    tracemalloc.start()
    try:
        with pytest.raises(ScenarioError, match=message):
            load_scenario(p)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 50e6  # bytes: nothing was expanded


def test_sizes_that_would_exhaust_the_machine_are_refused():
    with pytest.raises(ScenarioError, match=r"traffic.window.0: Input should be less than or equal "
                                            r"to 10000"):  # fmt: skip
        load_scenario("seamless", {"traffic": {"window": [1e7, 1e7]}})
    with pytest.raises(ScenarioError, match="traffic.participants 5000 is more than inner-city "
                                            "traffic holds: 200"):  # fmt: skip
        build_world(load_scenario("inner_city", {"traffic": {"participants": 5000}}))


def test_what_is_not_a_scenario_is_named(tmp_path):
    csv = tmp_path / "tracks.csv"
    csv.write_text("a,b\n")
    with pytest.raises(ScenarioError, match="a .csv file is not a scenario"):
        load_scenario(csv)
    with pytest.raises(ScenarioError, match="overrides must be a mapping of keys .*got list"):
        load_scenario("seamless", [1, 2])
    empty = tmp_path / "empty.yaml"
    for text in ("", "# a comment only\n"):
        empty.write_text(text)
        with pytest.raises(ScenarioError, match=r"empty.yaml: the file is empty \(or holds "
                                                r"only comments\); a scenario needs"):  # fmt: skip
            load_scenario(empty)


def test_a_file_written_from_scratch_gets_its_familys_defaults():
    """An inner-city file that says nothing of traffic drives at city speeds, a recorded one
    at the recorded traffic's; what a file states wins."""
    city = parse_scenario({"name": "mine", "road": {"type": "inner_city"}}).config
    builtin = load_scenario("inner_city").config
    assert (city.traffic.v_min, city.traffic.v_max, city.traffic.participants) == (2.77, 8.33, 20)
    assert city.ego.vehicle.v_max == builtin.ego.vehicle.v_max == 8.33
    assert city.ego.speed == builtin.ego.speed == 5.0
    faster = parse_scenario({"name": "m", "road": {"type": "inner_city"},
                             "traffic": {"v_max": 10.0}}).config  # fmt: skip
    assert faster.traffic.v_max == 10.0 and faster.traffic.v_min == 2.77
    seamless = parse_scenario({"name": "s", "road": {"type": "seamless"}}).config
    assert seamless.traffic.v_max == 13.88 and seamless.traffic.participants == 10
    recorded = load_scenario("us101_4_1").config
    assert recorded.ego.vehicle.v_max == 25.0 and recorded.env.speed_range == (0.0, 30.0)


@pytest.mark.parametrize("library", ["[tracks.csv]", "tracks.csv"])  # a list, or one alone
def test_a_scenario_extends_a_built_in_or_another_file(tmp_path, library):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "busy.yaml").write_text(
        "extends: inner_city\nname: busy\ntraffic:\n  participants: 40\n"
        f"  library: {library}\n")  # fmt: skip
    (tmp_path / "busier.yaml").write_text(
        "extends: sub/busy.yaml\nname: busier\nsimulation:\n  duration: 20\n"
    )
    busy = load_scenario(tmp_path / "sub" / "busy.yaml").config
    base = load_scenario("inner_city").config
    assert busy.traffic.participants == 40 and busy.road == base.road
    assert busy.model_dump(exclude={"name", "description", "traffic"}) == base.model_dump(
        exclude={"name", "description", "traffic"}
    )
    busier = load_scenario(tmp_path / "busier.yaml").config
    assert busier.name == "busier" and busier.simulation.duration == 20
    assert busier.traffic.participants == 40  # through two files
    # a relative path of the extended file names the same file from the extending one
    assert busier.traffic.library == [str(tmp_path / "sub" / "tracks.csv")]


@pytest.mark.parametrize(
    ("files", "message"),
    [
        (
            {"a.yaml": "extends: b.yaml\nname: a\n", "b.yaml": "extends: a.yaml\nname: b\n"},
            "extends goes round in a circle: .*a.yaml -> .*b.yaml -> .*a.yaml",
        ),
        (
            {"a.yaml": "extends: nowhere.yaml\nname: a\n"},
            "a.yaml: extends 'nowhere.yaml': scenario file not found",
        ),
        ({"a.yaml": "extends: [seamless]\nname: a\n"}, "extends must be a built-in scenario name"),
        ({"a.yaml": "extends: scene.xml\nname: a\n"}, "a CommonRoad file cannot be extended"),
        (
            {"a.yaml": "extends: b.yaml\nname: a\n", "b.yaml": "- not a mapping\n"},
            "b.yaml: a scenario must be a mapping of keys",
        ),
        ({"a.yaml": "extends: seamless\nname: a\nroad:\n  lanes: 0\n"}, "road.lanes"),
        (
            {"a.yaml": "extends: seamless\nroad:\n  lanes: 2\n"},
            "a.yaml: a scenario that extends 'seamless' needs a name of its own .* as 'seamless'",
        ),
    ],
)
def test_bad_extends_are_named(tmp_path, files, message):
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    with pytest.raises(ScenarioError, match=message):
        load_scenario(tmp_path / "a.yaml")


def test_an_extending_scenario_does_not_pass_for_its_parent(tmp_path):
    """Without a description of its own, a scenario that extends another says so (it was
    listed with the parent's, "GridSim Table I, inner-city column"); its own is kept."""
    (tmp_path / "busy.yaml").write_text("extends: inner_city\nname: busy\n")
    parent = load_scenario("inner_city").config.description
    assert load_scenario(tmp_path / "busy.yaml").config.description == (
        f"extends inner_city: {parent}")  # fmt: skip
    (tmp_path / "mine.yaml").write_text("extends: busy.yaml\nname: mine\ndescription: Mine.\n")
    assert load_scenario(tmp_path / "mine.yaml").config.description == "Mine."
    (tmp_path / "more.yaml").write_text("extends: busy.yaml\nname: more\n")  # not piled up
    assert load_scenario(tmp_path / "more.yaml").config.description == f"extends busy: {parent}"


def test_a_problem_with_a_key_of_the_extended_file_names_that_file(tmp_path):
    """A key the file does not set but inherits (``road.lanes`` of a seamless parent, wrong on
    the city road the file asks for) is said to come with its ``extends`` (also through a
    chain); a problem of the file's own key, or of a check that names one, is not (a key
    that contains an inherited one, a misspelt key hinted at an inherited one)."""
    (tmp_path / "highway.yaml").write_text(
        "name: hw\nroad: {type: seamless, lanes: 4}\nego: {speed: 5, lane: 2}\n"
    )
    path = tmp_path / "city.yaml"

    def problems(text: str) -> str:
        path.write_text("name: c\nextends: highway.yaml\n" + text)
        with pytest.raises(ScenarioError) as info:
            load_scenario(path)
        return str(info.value)

    came = "(not set in this file: it comes with extends: highway.yaml)"
    said = problems("road: {type: inner_city, lanes_per_direction: 99}\n")
    assert f"(got 4) {came}" in said and said.count(came) == 1  # (not lanes_per_direction's)
    assert came not in problems("ego: {speedx: 3}\n")  # (hinted at ego.speed)
    assert came not in problems("road: {lanes: 2}\n")  # ego.lane < road.lanes: this file's
    (tmp_path / "grand.yaml").write_text("name: g\nextends: city.yaml\n")
    path.write_text("name: c\nextends: highway.yaml\nroad: {type: inner_city}\n")
    with pytest.raises(
        ScenarioError,
        match=r"road.lanes: unknown key .*\(got 4\) \(not set in "
        r"this file: it comes with extends: city.yaml\)",
    ):
        load_scenario(tmp_path / "grand.yaml")


def test_an_extends_chain_is_bounded(tmp_path):
    for k in range(12):
        (tmp_path / f"s{k}.yaml").write_text(f"extends: s{k + 1}.yaml\nname: s{k}\n")
    (tmp_path / "s12.yaml").write_text("extends: seamless\nname: s12\n")
    with pytest.raises(ScenarioError, match="extends goes through more than 8 files") as err:
        load_scenario(tmp_path / "s0.yaml")
    assert str(err.value).startswith(f"{tmp_path / 's0.yaml'}: ")  # the file given, not s8
    assert load_scenario(tmp_path / "s6.yaml").config.name == "s6"


def test_an_extends_circle_given_by_a_relative_path_is_named_once_round(tmp_path, monkeypatch):
    """A relative path and the absolute ones ``extends`` resolves name the same file: the
    circle is found at its first return, shown in absolute paths, under the file given."""
    (tmp_path / "a.yaml").write_text("extends: b.yaml\nname: a\n")
    (tmp_path / "b.yaml").write_text("extends: a.yaml\nname: b\n")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ScenarioError) as err:
        load_scenario("a.yaml")
    a, b = tmp_path / "a.yaml", tmp_path / "b.yaml"
    assert str(err.value) == f"a.yaml: extends goes round in a circle: {a} -> {b} -> {a}"


def test_validate_reports_every_problem_of_a_file_at_once(tmp_path, capsys):
    """A key's own problem and the checks across keys, which run only on valid keys, come in
    one report; a check about a key that failed on its own is not guessed at."""
    path = tmp_path / "bad.yaml"
    path.write_text("name: x\nroad:\n  type: seamless\nego:\n  speed: 30\n  lane: 5\ntraffic:\n"
                    "  v_min: 9\n  v_max: 3\nenv:\n  decision_period: 0.15\n")  # fmt: skip
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "invalid scenario (4 problems):" in err
    for line in (
        "  - traffic: v_max (3.0) must be >= v_min (9.0)\n",
        "  - ego.speed (30.0) must be <= ego.vehicle.v_max (20.0)\n",
        "  - ego.lane (5) must be < road.lanes (3)\n",
        "  - env.decision_period (0.15) must be a whole multiple of simulation.dt",
    ):
        assert line in err  # fmt: skip
    path.write_text("name: x\nroad:\n  type: seamless\nego:\n  speed: 30\n  vehicle:\n"
                    "    v_max: fast\n")  # fmt: skip
    with pytest.raises(ScenarioError, match=r"\(1 problem\):\n  - ego.vehicle.v_max: "):
        load_scenario(path)


@pytest.mark.parametrize(
    ("section", "message"),
    [
        ({"sensor": {"max_range": 0.2, "cell_size": 0.5}},
         r"sensor: max_range \(0.2 m\) is shorter than a cell \(cell_size 0.5 m\)"),
        ({"ego": {"vehicle": {"length": 0.01, "width": 0.01, "wheelbase": 0.005}}},
         r"length 0.01 m x width 0.01 m is smaller than any car .*: sizes are in metres"),
        ({"sensor": {"mounts": [{"yaw_deg": 3.14159, "fov_deg": 90}]}},
         r"yaw_deg 3.14159 looks like radians \(3.14159 rad = 180 deg\)"),
    ],
)  # fmt: skip
def test_values_that_make_no_sense_are_refused(section, message):
    """Accepted before without a word: a sensor that sees no cell (every grid unknown), a
    1 cm ego, a rear-facing mount's yaw in radians."""
    with pytest.raises(ScenarioError, match=message):
        parse_scenario({"name": "x", "road": {"type": "seamless"}, **section}, "x.yaml")
    parse_scenario({"name": "x", "road": {"type": "seamless"},
                    "sensor": {"mounts": [{"yaw_deg": 3, "fov_deg": 90}]}}, "x.yaml")  # fmt: skip


@pytest.mark.parametrize(
    ("track", "message"),
    [
        ([], r"ego.track: an empty list names no track: give track ids, or 'random'"),
        (363.0, r"ego.track: track id 363.0 is neither text nor a whole number \(quote it as "
                r"written in the file, e.g. \"363\"\)"),
        ([363.0, 364], r"track id 363.0 is neither"),
        (True, r"track id True is neither"),
        (None, r"no track id given \(an empty ego.track: give an id, or 'random'\)"),
        ([[1]], r"track id \[1\] is neither"),
    ],
)  # fmt: skip
def test_ego_tracks_that_name_no_track_are_refused_in_plain_words(track, message):
    """An empty list ("the listed tracks have no track to use as the ego (of 0: none
    listed)"), an id saved as a float (pydantic's union: "ego.track.list[constrained-str]")."""
    doc = {"name": "x", "extends": "us101_3_3", "ego": {"track": track}}
    with pytest.raises(ScenarioError, match=message) as info:
        parse_scenario(doc, "x.yaml")
    assert "constrained-str" not in str(info.value) and "(1 problem)" in str(info.value)
    ids = parse_scenario({**doc, "ego": {"track": [363, "364", np.int64(365)]}}, "x.yaml")
    assert ids.config.ego.track == ["363", "364", "365"]


def test_a_one_lane_road_needs_no_ego_lane():
    """The ego's default lane (1) on a road of one lane is its only lane (the file was
    refused: "ego.lane (1) must be < road.lanes (1)"); a lane given is checked as before."""
    one = {"name": "a", "road": {"type": "seamless", "lanes": 1}}
    assert parse_scenario(one, "a.yaml").config.ego.lane == 0
    for lanes in (1.0, np.int64(1)):  # (as YAML or numpy may give it)
        lone = {**one, "road": {"type": "seamless", "lanes": lanes}}
        assert parse_scenario(lone, "a.yaml").config.ego.lane == 0
    assert parse_scenario({**one, "road": {"type": "seamless", "lanes": 3}}, "a.yaml"
                          ).config.ego.lane == 1  # fmt: skip
    with pytest.raises(ScenarioError, match=r"ego.lane \(1\) must be < road.lanes \(1\)"):
        parse_scenario({**one, "ego": {"lane": 1}}, "a.yaml")
    env = gym.make("GridSim-v0", scenario="seamless", road={"lanes": 1})
    obs, info = env.reset(seed=0)
    assert not env.step(info["reference_setpoints"])[2]


def test_generated_traffic_faster_than_40_m_s_is_warned_about():
    """50 m/s (a km/h slip for 50 km/h?) is legal but said: the human reference an ego
    follows collides more above 40 m/s. Recorded scenes, which ignore traffic.v_max, and the
    built-in scenarios say nothing."""
    import warnings

    from gridsim.errors import DataWarning

    with pytest.warns(DataWarning, match=r"traffic.v_max 50 m/s is 180 km/h: speeds are in m/s"):
        load_scenario("seamless", {"traffic": {"v_max": 50}})
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        for name in ("seamless", "inner_city"):
            load_scenario(name, {"traffic": {"v_max": 40}})
