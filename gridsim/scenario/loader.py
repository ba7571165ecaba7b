"""Load scenarios by built-in name, by YAML path or from a CommonRoad XML file, with validated
overrides."""

from __future__ import annotations

import difflib
import math
import os
import re
import typing
from collections.abc import Mapping, Sequence
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from pydantic import ValidationError

from gridsim.errors import ScenarioError, archive_problem, not_there, warn_data
from gridsim.outputs import counted
from gridsim.scenario.family import FAMILIES, family_defaults
from gridsim.scenario.schema import (
    MAX_WHEELBASE_SHARE,
    ZERO_PADDED,
    Scenario,
    ScenarioConfig,
    Strict,
)

_BUILTIN_DIR = ("data", "scenarios")


class _UniqueKeyLoader(yaml.SafeLoader):
    """YAML's safe loader, refusing a key given twice in one mapping (YAML would keep the
    last silently, and a second ``traffic:`` block would replace the first)."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            first: dict = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    seen = first.setdefault(key, key_node.start_mark)
                except TypeError:  # unhashable: the base loader names it
                    continue
                if seen is not key_node.start_mark:
                    raise yaml.constructor.ConstructorError(
                        None, None,
                        f"duplicate key {key!r} (first at line {seen.line + 1}, again at line "
                        f"{key_node.start_mark.line + 1})",
                        key_node.start_mark,
                    )  # fmt: skip
        return super().construct_mapping(node, deep=deep)

    def construct_yaml_int(self, node):
        """An integer, but one written with a leading zero (``00427``: a zero-padded track
        id) as written, a string: YAML 1.1 reads it as octal (279), an id never written."""
        if ZERO_PADDED.match(node.value):
            return node.value
        return super().construct_yaml_int(node)


_UniqueKeyLoader.add_constructor("tag:yaml.org,2002:int", _UniqueKeyLoader.construct_yaml_int)


#: Bounds on a scenario YAML document (the built-in ones are under 4 KB, 300 nodes, depth 5),
#: so that a hostile file (nested aliases, deep nesting) is refused at once: its size
#: [bytes], its nodes with every alias expanded, and its nesting depth.
MAX_YAML_BYTES, MAX_YAML_NODES, MAX_YAML_DEPTH = 1_000_000, 100_000, 50


def _load_yaml(text: str, source: str) -> Any:
    """The YAML document ``text`` (safe, duplicate keys refused), after checking the bounds
    :data:`MAX_YAML_BYTES`, :data:`MAX_YAML_NODES` and :data:`MAX_YAML_DEPTH` on its node
    graph, before anything is expanded."""
    if len(text) > MAX_YAML_BYTES:
        raise ScenarioError(f"{source}: {len(text):,} characters; a scenario file has at most "
                            f"{MAX_YAML_BYTES:,}")  # fmt: skip
    depth = _flow_depth(text)
    if depth > MAX_YAML_DEPTH:  # YAML's scanner is slow on deep [ { nesting: refused first
        raise ScenarioError(f"{source}: brackets nested {depth} levels deep; at most "
                            f"{MAX_YAML_DEPTH}")  # fmt: skip
    loader = _UniqueKeyLoader(text)
    try:
        try:
            node = loader.get_single_node()
        except RecursionError:
            raise ScenarioError(f"{source}: nested deeper than YAML can read (at most "
                                f"{MAX_YAML_DEPTH} levels)") from None  # fmt: skip
        if node is None:
            return None
        nodes, depth = _expanded_size(node, source)
        if depth > MAX_YAML_DEPTH:
            raise ScenarioError(f"{source}: nested {depth} levels deep; at most {MAX_YAML_DEPTH}")
        if nodes > MAX_YAML_NODES:
            raise ScenarioError(f"{source}: {nodes:,} values once its aliases are expanded; at "
                                f"most {MAX_YAML_NODES:,} (nested aliases?)")  # fmt: skip
        return loader.construct_document(node)
    finally:
        loader.dispose()


_QUOTED = re.compile(r'"(?:[^"\\]|\\.)*"|\'(?:[^\']|\'\')*\'')


def _flow_depth(text: str) -> int:
    """The deepest nesting of ``[`` and ``{`` outside quoted strings (an upper bound of the
    document's flow nesting: brackets in comments count too)."""
    bare = _QUOTED.sub("", text)
    steps = np.frombuffer(bare.encode(), np.uint8)
    delta = np.isin(steps, (ord("["), ord("{"))).astype(np.int64)
    delta -= np.isin(steps, (ord("]"), ord("}")))
    return int(np.cumsum(delta).max(initial=0))


def _expanded_size(root: yaml.Node, source: str) -> tuple[int, int]:
    """``(nodes, depth)`` of a YAML node graph with every alias expanded, counted without
    expanding (each distinct node once); a :class:`ScenarioError` for a recursive alias."""
    size: dict[int, tuple[int, int]] = {}
    open_nodes: set[int] = set()
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        children = []
        if isinstance(node, yaml.SequenceNode):
            children = node.value
        elif isinstance(node, yaml.MappingNode):
            children = [n for pair in node.value for n in pair]
        if done:
            open_nodes.discard(key)
            parts = [size[id(c)] for c in children]
            size[key] = (1 + sum(p[0] for p in parts), 1 + max((p[1] for p in parts), default=0))
            continue
        if key in size:
            continue
        if key in open_nodes:
            raise ScenarioError(f"{source}: a recursive alias (an anchor used inside itself)")
        open_nodes.add(key)
        stack.append((node, True))
        stack += [(c, False) for c in children if id(c) not in size]
    return size[id(root)]


def builtin_scenarios() -> dict[str, str]:
    """Built-in scenario names and their one-line descriptions."""
    folder = resources.files("gridsim").joinpath(*_BUILTIN_DIR)
    out = {}
    for entry in sorted(folder.iterdir(), key=lambda e: e.name):
        if entry.name.endswith(".yaml"):
            doc = yaml.safe_load(entry.read_text())
            out[entry.name[:-5]] = str(doc.get("description", "")).strip().splitlines()[0:1]
    return {k: (v[0] if v else "") for k, v in out.items()}


def _models(annotation: Any) -> list[type]:
    """The :class:`Strict` models a field of ``annotation`` holds (in a list or union too)."""
    if isinstance(annotation, type) and issubclass(annotation, Strict):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in _models(arg)]


def _known_paths() -> list[str]:
    """Every key path the schema knows (``traffic.participants``, ``road.lanes``, ...)."""
    out: set[str] = set()

    def walk(model: type, prefix: str) -> None:
        for name, f in model.model_fields.items():
            out.add(prefix + name)
            for sub in _models(f.annotation):
                walk(sub, f"{prefix}{name}.")

    walk(ScenarioConfig, "")
    return sorted(out)


def _did_you_mean(parts: list, family: str | None = None) -> str:
    """A hint for the unknown key at ``parts``: a ``road`` key of another ``family`` than the
    file's is named so, with the closest key of the file's family; else the closest spelling
    among its siblings, else the full path of a key of that name elsewhere (a key at the
    wrong level), else the closest spelling anywhere."""
    if not parts:
        return ""
    key, given = str(parts[-1]), ".".join(map(str, parts))
    if family is not None and len(parts) == 2 and parts[0] == "road":
        owners = [tag for tag, f in FAMILIES.items() if key in f.config.model_fields]
        if owners:
            mine = [k for k in FAMILIES[family].config.model_fields if k != "type"]
            # a key that contains the other (lanes, lanes_per_direction); not a spelling
            # match: road.seed is no misspelt road.scene
            close = [k for k in mine if key in k or k in key]
            instead = f"; did you mean 'road.{close[0]}'?" if close else ""
            return (f" for road type {family!r} (a key of {', '.join(map(repr, owners))})"
                    f"{instead}")  # fmt: skip
    parent = given.rpartition(".")[0]
    paths = _known_paths()
    siblings = [p for p in paths if p.rpartition(".")[0] == parent]
    close = difflib.get_close_matches(given, siblings, n=1, cutoff=0.8)
    if not close:
        close = [p for p in paths if p.rsplit(".", 1)[-1] == key and p != given][:1]
    if not close:
        names = {p.rsplit(".", 1)[-1]: p for p in paths}
        close = [names[n] for n in difflib.get_close_matches(key, list(names), n=1, cutoff=0.7)]
    return f" (did you mean {close[0]!r}?)" if close else ""


def _format_validation(source: str, problems: list[str]) -> str:
    return "\n".join([f"{source}: invalid scenario ({counted(len(problems), 'problem')}):",
                      *(f"  - {p}" for p in problems)])  # fmt: skip


def _problems(err: ValidationError) -> list[tuple[tuple, str]]:
    """``(key path, line)`` per problem of ``err``; a check across keys (a ``ValueError`` of
    a model validator, several lines for several problems) in its own words."""
    out = []
    for e in err.errors():
        parts = list(e["loc"])
        family = None
        if len(parts) > 1 and parts[0] == "road" and parts[1] in FAMILIES:
            family = parts.pop(1)  # pydantic's union tag is not part of the user's key path
        loc = ".".join(str(p) for p in parts) or "(top level)"
        msg = e["msg"].removeprefix("Value error, ")  # (a validator's own words)
        if e["type"] == "extra_forbidden":
            msg = "unknown key" + _did_you_mean(parts, family)
        got = e.get("input")
        if e["type"] in ("union_tag_invalid", "union_tag_not_found") and parts == ["road"]:
            tag = got.get("type") if isinstance(got, Mapping) else None
            close = difflib.get_close_matches(str(tag), list(FAMILIES), n=1, cutoff=0.6)
            hint = f" (did you mean {close[0]!r}?)" if close and tag is not None else ""
            said = "is missing" if tag is None else f"{tag!r} is no scenario family{hint}"
            out.append((("road", "type"), f"road.type {said}; the families: "
                                           f"{', '.join(FAMILIES)}"))  # fmt: skip
            continue
        if e["type"] == "missing" and parts and isinstance(parts[-1], int):  # a short list
            whole = ".".join(str(p) for p in parts[:-1])
            what = _description(parts[:-1], family)
            out.append((tuple(parts[:-1]), f"{whole}: too few values (no item {parts[-1] + 1})"
                        + (f"; {what}" if what else "")))  # fmt: skip
            continue
        if e["type"] == "missing":  # (pydantic's "Field required (got {...})": the section)
            out.append((tuple(parts), f"{loc} is missing; it is required"))
            continue
        if e["type"] == "value_error" and isinstance(got, Mapping):  # across keys: no input
            for line in msg.splitlines():
                out.append((tuple(parts), f"{loc}: {line}" if parts else line))
            continue
        shown = repr(got) if not isinstance(got, Mapping) else "{...}"
        if len(shown) > 60:
            shown = shown[:57] + "..."
        what = _description(parts, family) if e["type"] in _RANGE_ERRORS else None
        if what and re.fullmatch(r"\[[^\[\]]*\]", what):  # a bare unit: "[m/s]"
            what = f"unit: {what[1:-1]}"
        out.append((tuple(parts), f"{loc}: {msg} (got {shown})" + (f"; {what}" if what else "")))
    return out


#: pydantic's errors of a number out of its range: they are shown with the key's description
#: (its unit: "simulation.dt: ... less than or equal to 1 (got 100); simulation time step [s]").
_RANGE_ERRORS = ("greater_than", "greater_than_equal", "less_than", "less_than_equal")


def _description(parts: list, family: str | None) -> str | None:
    """The schema's description of the key at ``parts`` (``road`` keys: of ``family``)."""
    model: Any = ScenarioConfig
    parts = [p for p in parts if not isinstance(p, int)]  # (a list's items: sensor.mounts.0.x)
    for k, part in enumerate(parts):
        if k == 1 and parts[0] == "road" and family in FAMILIES:
            model = FAMILIES[family].config
        fields = getattr(model, "model_fields", {})
        if part not in fields:
            return None
        if k == len(parts) - 1:
            return fields[part].description
        model = next(iter(_models(fields[part].annotation)), None)
    return None


def _validate(
    doc: dict[str, Any],
    source: str,
    given: Sequence[str] = (),
    inherited: tuple = (None, (), set()),
) -> ScenarioConfig:
    """``doc`` validated; else a :class:`ScenarioError` listing every problem at once (those
    about a key path of ``given``, the keyword overrides, said to be theirs; those about a
    key ``inherited`` ``(parent, paths, the file's own paths)`` through ``extends``, said to
    come with it). The
    checks across keys run only on keys that are valid each on its own, so a failed document
    is checked again with its failing keys left to their defaults (up to 3 times), and the
    problems that this finds about keys that did not fail are added."""
    problems: list[str] = []
    removed: list[str] = []
    for _ in range(3):
        try:
            cfg = ScenarioConfig.model_validate(doc)
        except ValidationError as exc:
            found = _problems(exc)
        else:
            if not problems:
                return cfg
            break
        new = [line for _, line in found if line not in problems
               and not any(_about(line, path) for path in removed)]  # fmt: skip
        problems += new
        paths = [parts for parts, _ in found if parts]
        if not new or not paths:
            break
        for parts in paths:
            doc = _without(doc, parts)
            removed.append(".".join(map(str, parts)))
    problems = [f"(keyword override) {line}" if any(_about(line, p) for p in given) else line
                for line in problems]  # fmt: skip
    parent, paths, own = inherited
    problems = [f"{line} (not set in this file: it comes with extends: {parent})"
                if _inherited_problem(line, paths, own) else line for line in problems]  # fmt: skip
    raise ScenarioError(_format_validation(source, problems))


def _inherited_problem(line: str, inherited: Sequence[str], own: set[str]) -> bool:
    """Whether the problem ``line`` is about a key the file inherits (``inherited``: through
    ``extends``): it starts with that key, and names none of the file's ``own`` keys."""
    if not any(re.match(rf"{re.escape(p)}(:| \()", line) for p in inherited):
        return False
    return not any(re.search(rf"(?<![\w.']){re.escape(k)}(?![\w'])", line) for k in own)


def _about(line: str, path: str) -> bool:
    """Whether the problem ``line`` is about the key ``path`` (dotted), which was left to its
    default: it names the key, or it is a check of the key's section that names its leaf
    (``road: jitter (20.0) must be < block_size / 4 (11.25)`` ran on the default block
    size)."""
    section, _, leaf = path.rpartition(".")
    return path in line or bool(section) and line.startswith(f"{section}:") and leaf in line


def _without(doc: Mapping[str, Any], parts: tuple) -> dict[str, Any]:
    """``doc`` without the key at ``parts`` (a list item: the list's key)."""
    out = dict(doc)
    key = parts[0]
    if len(parts) > 1 and isinstance(out.get(key), Mapping) and not isinstance(parts[1], int):
        out[key] = _without(out[key], parts[1:])
    else:
        out.pop(key, None)
    return out


def _key_paths(doc: Mapping[str, Any], prefix: str = "") -> list[str]:
    """The dotted paths of the leaves of ``doc`` (``traffic.participants``)."""
    out = []
    for k, v in doc.items():
        path = f"{prefix}{k}"
        out += _key_paths(v, path + ".") if isinstance(v, Mapping) and v else [path]
    return out


def deep_merge(base: Mapping[str, Any], overrides: Mapping[str, Any]) -> dict[str, Any]:
    """Recursively merge ``overrides`` into ``base`` (mappings merge, other values replace)."""
    out = dict(base)
    for k, v in overrides.items():
        if isinstance(v, Mapping) and isinstance(out.get(k), Mapping):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = v
    return out


#: How many files an ``extends:`` chain may pass through.
MAX_EXTENDS = 8


def parse_scenario(
    doc: Any,
    source: str = "<scenario>",
    base_dir: Path | None = None,
    overrides: Mapping[str, Any] | None = None,
    shared: bool = False,
) -> Scenario:
    """Validate a parsed YAML document (plus ``overrides``) into a :class:`Scenario`: the
    scenario it ``extends:`` first, if any (:func:`_extended`), then its road family's
    defaults (:attr:`~gridsim.scenario.family.Family.defaults`), then the document, then
    ``overrides``. Keys the road family does not read are warned about; with ``shared``
    (``overrides`` given to every scenario of a collection, whose other members read them)
    only those the document sets."""
    _check_mapping(doc, source)
    if overrides is not None and not isinstance(overrides, Mapping):
        raise ScenarioError(f"{source}: overrides must be a mapping of keys (like the YAML), "
                            f"got {type(overrides).__name__}")  # fmt: skip
    parent = doc.get("extends")
    mine = set(_key_paths(doc))
    doc = own = _extended(doc, source, base_dir)
    inherited = [p for p in _key_paths(own) if p not in mine] if parent else []
    if overrides:
        doc = deep_merge(doc, overrides)
    road = doc.get("road")
    family = road.get("type") if isinstance(road, Mapping) else None
    unused = _unused_keys(own if shared else doc, family)
    doc = deep_merge(family_defaults(family), doc)
    given = _key_paths(overrides) if overrides else []  # (a problem may be theirs)
    scenario = Scenario(_validate(doc, source, given, (parent, inherited, mine)), source, base_dir)
    _warn_fast_traffic(scenario, family)
    _warn_timing(scenario, family)
    _warn_wheelbase(scenario, family)
    if unused:
        ignores, by_why = FAMILIES[family].ignores, {}
        for key in unused:
            by_why.setdefault(ignores[key], []).append(key)
        said = "; ".join(f"{', '.join(keys)} not used by road type {family!r} ({why})"
                         for why, keys in by_why.items())  # fmt: skip
        warn_data(f"{source}: {said}; ignored")
    return scenario


#: m/s: generated traffic faster than this is warned about (a km/h slip, or speeds the
#: scripted human reference is not kept clear at: docs/environment.md, the reference).
FAST_TRAFFIC = 40.0


def _warn_fast_traffic(scenario: Scenario, family: Any) -> None:
    """A :class:`~gridsim.errors.DataWarning` when a family that reads ``traffic.v_max``
    drives faster than :data:`FAST_TRAFFIC`."""
    v = scenario.config.traffic.v_max
    if v > FAST_TRAFFIC and family in FAMILIES and "traffic.v_max" not in FAMILIES[family].ignores:
        warn_data(f"{scenario.source}: traffic.v_max {v:g} m/s is {v * 3.6:.0f} km/h: speeds "
                  f"are in m/s (km/h / 3.6); above {FAST_TRAFFIC:g} m/s an ego following the "
                  "human reference collides more often (3-7 of 8 seamless episodes at 40-70 "
                  "m/s)")  # fmt: skip


def _warn_wheelbase(scenario: Scenario, family: Any) -> None:
    """A :class:`~gridsim.errors.DataWarning` when ``ego.vehicle.wheelbase`` is shortened
    (more than :data:`~gridsim.scenario.schema.MAX_WHEELBASE_SHARE` of the length; on a
    family whose ego takes a track's size, the track's length decides, episode by episode)."""
    vehicle = scenario.config.ego.vehicle
    top = MAX_WHEELBASE_SHARE * vehicle.length
    if vehicle.wheelbase > top + 1e-9 and "ego.vehicle.length" not in FAMILIES[family].ignores:
        warn_data(f"{scenario.source}: ego.vehicle.wheelbase {vehicle.wheelbase:g} m is more than "
                  f"{MAX_WHEELBASE_SHARE:g} x ego.vehicle.length {vehicle.length:g} m: the "
                  f"car is driven with a wheelbase of {top:.4g} m")  # fmt: skip


def _warn_timing(scenario: Scenario, family: Any) -> None:
    """A :class:`~gridsim.errors.DataWarning` when the set-points are closer than a tick, or
    a decision lasts past the first set-point (the car then passes set-points of a plan it
    follows blind until the next decision; ``l1`` scores the plan, not where the car is), or
    (on a generated road; a recorded scene's episodes last as its tracks) an episode's
    duration is not a whole number of decisions (it ends after the decision that passes it)."""
    env, dt = scenario.config.env, scenario.config.simulation.dt
    said = []
    if env.setpoint_period < dt - 1e-9:
        said.append(f"env.setpoint_period {env.setpoint_period:g} s is shorter than a tick "
                    f"(simulation.dt {dt:g} s)")  # fmt: skip
    if env.decision_period > env.setpoint_period + 1e-9:
        said.append(f"a decision (env.decision_period {env.decision_period:g} s) outlasts the "
                    f"first set-point (env.setpoint_period {env.setpoint_period:g} s): the car "
                    "passes set-points of a plan it follows until the next decision")  # fmt: skip
    if said:
        warn_data(f"{scenario.source}: {'; '.join(said)}; l1 scores the plans, not where the "
                  "car gets: a policy may score well and drive poorly")  # fmt: skip
    duration = scenario.config.simulation.duration
    decisions = duration / env.decision_period
    whole = abs(decisions - round(decisions)) <= 1e-6 * max(decisions, 1.0)
    if not whole and not FAMILIES[family].recorded:
        last = math.ceil(decisions - 1e-6)
        warn_data(f"{scenario.source}: simulation.duration {duration:g} s is not a whole "
                  f"number of decisions (env.decision_period {env.decision_period:g} s): an "
                  f"episode ends after its decision {last}, at "
                  f"{last * env.decision_period:g} s")  # fmt: skip


def _unused_keys(doc: Mapping[str, Any], family: Any) -> list[str]:
    """The keys the user set (``doc``, before the family's defaults) to other than their
    default (the family's, else the schema's) that road type ``family`` does not use (none
    for an unknown family: the schema names it). A resolved scenario (``validate
    --resolved``) states every key at its default."""
    if not isinstance(family, str) or family not in FAMILIES:
        return []
    fields, own = ScenarioConfig.model_fields, family_defaults(family)

    def default(path: list[str]) -> Any:  # the family's, else the schema's
        mine = value_at(own, path)
        if mine is not MISSING:
            return mine
        return value_at(fields[path[0]].default.model_dump(), path[1:])

    unused = []
    for key in FAMILIES[family].ignores:
        path = key.split(".")
        value = value_at(doc, path)
        if value is not MISSING and not _same(value, default(path)):
            unused.append(key)
    return unused


#: What :func:`value_at` gives for a key that is not there.
MISSING = object()


def value_at(doc: Any, path: str | Sequence[str]) -> Any:
    """The value at the key ``path`` (dotted, ``ego.vehicle.length``, or its parts) of nested
    mappings ``doc`` (:data:`MISSING` if absent)."""
    for key in path.split(".") if isinstance(path, str) else path:
        if not isinstance(doc, Mapping) or key not in doc:
            return MISSING
        doc = doc[key]
    return doc


def _same(value: Any, default: Any) -> bool:
    """Whether a YAML ``value`` states ``default`` (a list for a tuple too)."""
    try:
        if isinstance(value, list | tuple) and isinstance(default, list | tuple):
            return list(value) == list(default)
        return bool(value == default)
    except Exception:  # a value of another kind entirely: the schema will say
        return False


def _check_mapping(doc: Any, source: str) -> None:
    """A :class:`ScenarioError` unless ``doc`` is a mapping with text keys."""
    if doc is None:
        raise ScenarioError(f"{source}: the file is empty (or holds only comments); a scenario "
                            "needs at least name: and road: {type: ...}")  # fmt: skip
    if not isinstance(doc, Mapping):
        raise ScenarioError(
            f"{source}: a scenario must be a mapping of keys, got {type(doc).__name__}"
        )
    if any(not isinstance(k, str) for k in doc):
        raise ScenarioError(f"{source}: all top-level keys must be strings")


def _file_key(source: str) -> str:
    """``source`` (a path as given, or ``builtin:NAME``) as one name per file: a file's
    absolute path, ``builtin:NAME`` as it is (to compare and to show ``extends`` chains)."""
    return source if source.startswith("builtin:") else str(Path(source).resolve())


def _extended(doc: Mapping[str, Any], source: str, base_dir: Path | None,
              chain: tuple[str, ...] = ()) -> dict[str, Any]:  # fmt: skip
    """``doc`` merged over the scenario its ``extends:`` names (a built-in name, or a YAML
    path relative to ``base_dir``; that one's own ``extends:`` first), whose relative file
    paths are made absolute; ``doc`` itself if it extends nothing. A :class:`ScenarioError`
    for a reference that is not a scenario, a cycle or a chain longer than
    :data:`MAX_EXTENDS`."""
    if "extends" not in doc:
        return dict(doc)
    ref = doc["extends"]
    if not isinstance(ref, str) or not ref.strip():
        raise ScenarioError(f"{source}: extends must be a built-in scenario name or a path to a "
                            f"YAML scenario file, got {ref!r}")  # fmt: skip
    if Path(ref).suffix.lower() == ".xml":
        raise ScenarioError(f"{source}: extends {ref!r}: a CommonRoad file cannot be extended; "
                            "write its YAML with `gridsim import`, then extend that")  # fmt: skip
    target = ref
    if base_dir is not None and (Path(ref).suffix in (".yaml", ".yml") or "/" in ref):
        target = str(base_dir / ref)
    first = chain[0] if chain else source  # (named first: the file the user gave)
    if len(chain) >= MAX_EXTENDS:
        raise ScenarioError(f"{first}: extends goes through more than {MAX_EXTENDS} files: "
                            f"{' -> '.join(map(_file_key, (*chain, source)))} -> ...")  # fmt: skip
    try:
        text, parent_source, parent_dir = _read(target)
    except ScenarioError as exc:
        raise ScenarioError(f"{source}: extends {ref!r}: {exc}") from None
    steps = [_file_key(s) for s in (*chain, source, parent_source)]
    if steps[-1] in steps[:-1]:
        raise ScenarioError(f"{first}: extends goes round in a circle: "
                            f"{' -> '.join(steps)}")  # fmt: skip
    parent = _parse_yaml(text, parent_source)
    _check_mapping(parent, parent_source)
    parent = _extended(parent, parent_source, parent_dir, (*chain, source))
    own = {k: v for k, v in doc.items() if k != "extends"}
    if "name" not in own:
        raise ScenarioError(f"{source}: a scenario that extends {ref!r} needs a name of its own "
                            f"(name: ...); it would be listed, recorded and reported as "
                            f"{parent.get('name')!r}")  # fmt: skip
    if "description" not in own and parent.get("description"):  # (it describes the parent)
        words = re.sub(r"^extends [^:]*: ", "", str(parent["description"]))  # (once, in a chain)
        own["description"] = f"extends {parent.get('name')}: {words}"
    return deep_merge(absolute_paths(parent, parent_dir), own)


def absolute_paths(doc: dict[str, Any], base_dir: Path | None) -> dict[str, Any]:
    """``doc`` with its relative file paths (``road.map``, ``traffic.library`` files) made
    absolute against ``base_dir``, so that they name the same files from another folder."""
    if base_dir is None:
        return doc

    def absolute(ref: Any) -> Any:
        if not isinstance(ref, str) or ref in ("builtin", "scene") or ref.startswith("builtin:"):
            return ref
        return ref if Path(ref).is_absolute() else str(base_dir / ref)

    out = dict(doc)
    if isinstance(out.get("road"), Mapping) and "map" in out["road"]:
        out["road"] = {**out["road"], "map": absolute(out["road"]["map"])}
    library = out["traffic"].get("library") if isinstance(out.get("traffic"), Mapping) else None
    if isinstance(library, str):  # one alone
        library = [library]
    if isinstance(library, list):
        out["traffic"] = {**out["traffic"], "library": [absolute(r) for r in library]}
    return out


def commonroad_defaults() -> dict[str, Any]:
    """The scenario of a CommonRoad file given as is (see :func:`commonroad_scenario`): the
    recorded family's defaults, with the scene's own tracks and an episode as long as the
    ego's."""
    return deep_merge(family_defaults("recorded"), {
        "simulation": {"dt": 0.1, "duration": 3600.0},
        "traffic": {"library": ["scene"]},
        "ego": {"track": "random"},
    })  # fmt: skip


def _where(path: Path) -> str:
    """``path`` as given, and where it was looked for if relative ("x.yaml (looked for as
    /home/me/x.yaml)")."""
    if path.is_symlink():
        return not_there(path)
    return str(path) if path.is_absolute() else f"{path} (looked for as {path.resolve()})"


def commonroad_scenario(
    path: Path, overrides: Mapping[str, Any] | None = None, shared: bool = False
) -> Scenario:
    """A CommonRoad scenario file as it is: its lanelet map and its dynamic obstacles, one
    of them the ego (drawn from the seed), with :func:`commonroad_defaults` and ``overrides``."""
    if not path.is_file():
        raise ScenarioError(f"scenario file not found: {_where(path)}")
    doc = deep_merge(
        commonroad_defaults(),
        {
            "name": path.stem[:80],
            "description": f"CommonRoad scene {path.name}; one recorded vehicle is the ego",
            "road": {"type": "recorded", "map": str(path.resolve())},
        },
    )
    return parse_scenario(doc, str(path), path.resolve().parent, overrides, shared)


def load_scenario(
    name_or_path: str | Path, overrides: Mapping[str, Any] | None = None, shared: bool = False
) -> Scenario:
    """Load a built-in scenario by name (``"seamless"``), a YAML file by path, or a
    CommonRoad XML file (``.xml``, see :func:`commonroad_scenario`); ``shared``: see
    :func:`parse_scenario`."""
    if isinstance(name_or_path, str | os.PathLike) and Path(name_or_path).suffix.lower() == ".xml":
        return commonroad_scenario(Path(name_or_path), overrides, shared)
    text, source, base = _read(name_or_path)
    return parse_scenario(_parse_yaml(text, source), source, base, overrides, shared)


def scenario_document(path: str | Path) -> Any:
    """The YAML document of the scenario file ``path``, read as :func:`load_scenario` reads
    it (its bounds, duplicate keys refused, numbers with leading zeros kept as written),
    not yet checked against the schema; a :class:`ScenarioError` if it cannot be read."""
    text, source, _ = _read(path)
    return _parse_yaml(text, source)


def _parse_yaml(text: str, source: str) -> Any:
    """The YAML document ``text`` of ``source``; a :class:`ScenarioError` saying where it is
    malformed."""
    try:
        return _load_yaml(text, source)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise ScenarioError(f"{source}: malformed YAML{where}: {problem}") from None


def names_a_file(ref: str | Path) -> bool:
    """Whether the scenario reference ``ref`` is read as a file (a YAML or CommonRoad XML
    suffix, or a path of folders), not looked up as a built-in name."""
    p = Path(ref)
    return p.suffix in (".yaml", ".yml") or p.suffix.lower() == ".xml" or len(p.parts) > 1


def check_reference(ref: Any) -> None:
    """A :class:`ScenarioError` unless ``ref`` can name scenarios: a non-empty string or path
    (an empty one named the current folder)."""
    if not isinstance(ref, str | os.PathLike):
        several = ""
        if (isinstance(ref, list | tuple) and ref
                and all(isinstance(r, str | os.PathLike) for r in ref)):  # fmt: skip
            joined = ",".join(map(str, ref))
            several = f"; several as one text, separated by commas: scenario={joined!r}"
        raise ScenarioError(f"scenario must be a built-in name, a YAML or XML path, a folder or "
                            f"glob of them, or a Scenario, got "
                            f"{ref!r} ({type(ref).__name__}){several}")  # fmt: skip
    if not str(ref).strip():
        raise ScenarioError(f"scenario is empty: give a built-in name "
                            f"({', '.join(builtin_scenarios())}), a YAML or XML file, or a "
                            "folder or glob of them")  # fmt: skip


def _read(name_or_path: str | Path) -> tuple[str, str, Path | None]:
    check_reference(name_or_path)
    p = Path(name_or_path)
    looks_like_path = names_a_file(p)
    if p.is_dir():
        raise ScenarioError(
            f"{p} is a folder: a scenario collection, not one scenario file (gym.make and the "
            "commands that accept collections take it; see gridsim.scenario.collection)"
        )
    if p.suffix.lower() in (".csv", ".npz", ".json", ".mp4", ".png"):
        raise ScenarioError(f"{p}: a {p.suffix} file is not a scenario (give a .yaml, "
                            ".yml or CommonRoad .xml file; trajectory CSVs go in "
                            "traffic.library)")  # fmt: skip
    if looks_like_path:
        if not p.exists():
            raise ScenarioError(f"scenario file not found: {_where(p)}")
        if not p.is_file():
            raise ScenarioError(f"{p}: not a regular file (a scenario is a .yaml or .xml file)")
        try:
            return p.read_text(encoding="utf-8"), str(p), p.resolve().parent
        except (OSError, UnicodeDecodeError) as exc:
            archive = archive_problem(p)
            said = archive if archive else f"cannot read scenario file ({exc})"
            raise ScenarioError(f"{p}: {said}") from None
    entry = resources.files("gridsim").joinpath(*_BUILTIN_DIR, f"{name_or_path}.yaml")
    if not entry.is_file():
        names = builtin_scenarios()
        close = difflib.get_close_matches(str(name_or_path), names, n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ScenarioError(
            f"unknown scenario {str(name_or_path)!r}{hint}; built-in scenarios: "
            f"{', '.join(names)} (or give a path to a .yaml or a CommonRoad .xml file)"
        )
    return entry.read_text(encoding="utf-8"), f"builtin:{name_or_path}", None
