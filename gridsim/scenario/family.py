"""Scenario families: what a scenario file's ``road.type`` names, one registry entry each.

A family is a road module (``gridsim/road/``), a family module that describes it and
registers it (``gridsim/scenario/families/NAME.py``: its typed ``road:`` block, its world
builder, its defaults) and the YAML files that use it. Everything else is derived from the
registry: the schema's ``road:`` union (:class:`~gridsim.scenario.schema.ScenarioConfig`),
the loader's defaults per family and its error paths, the world builders, the data checks.

The built-in families (seamless, inner_city, recorded) register when ``gridsim.scenario``
is imported; a plugin registers its own with :func:`register_family` before it loads a
scenario of that family.
"""

from __future__ import annotations

import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Annotated, Any

from pydantic import Field
from pydantic.fields import FieldInfo

from gridsim.errors import ScenarioError
from gridsim.scenario.schema import ScenarioConfig, Strict

if TYPE_CHECKING:  # the loader and the world import this module's users, not this module
    from gridsim.scenario.checks import SceneReport
    from gridsim.scenario.schema import Scenario
    from gridsim.world.world import World


@dataclass(frozen=True)
class Family:
    """One scenario family.

    - ``config``: the pydantic model of its ``road:`` block (a :class:`Strict` model whose
      ``type`` is ``Literal[tag]``; the tag is read from it);
    - ``build``: ``(scenario, seed) -> World``, the world of an episode seed;
    - ``defaults``: what a file of this family gets where it is silent, before the schema's
      own defaults (a nested mapping like the YAML);
    - ``recorded``: its scenes replay recorded tracks, one of them the ego's (the human
      reference is that track's future; ``traffic.library: [scene]`` reads the map's);
    - ``data_report``: ``scenario -> SceneReport``, the plausibility of its recorded data
      (:mod:`gridsim.scenario.checks`), or None for a family without data;
    - ``ignores``: the keys (``section.key`` or deeper, ``ego.vehicle.length``) of the
      other sections its worlds never read, each with why (a file that sets one is warned
      about: the key has no effect).
    """

    config: type[Strict]
    build: Callable[[Scenario, int], World]
    defaults: Mapping[str, Any] = field(default_factory=dict)
    recorded: bool = False
    data_report: Callable[[Scenario], SceneReport] | None = None
    ignores: Mapping[str, str] = field(default_factory=dict)

    @property
    def tag(self) -> str:
        """``road.type`` in YAML."""
        return _tag_of(self.config)


#: The registered families by tag, in the order of registration.
FAMILIES: dict[str, Family] = {}


def _tag_of(config: type) -> str:
    if not (isinstance(config, type) and issubclass(config, Strict)):
        raise TypeError(f"a family's config must be a gridsim Strict model, got {config!r}")
    annotation = config.model_fields.get("type")
    tags = typing.get_args(annotation.annotation) if annotation is not None else ()
    if len(tags) != 1 or not isinstance(tags[0], str):
        raise TypeError(f"{config.__name__} needs a field type: Literal['NAME'] (its tag)")
    return tags[0]


def register_family(family: Family) -> Family:
    """Add ``family`` to :data:`FAMILIES` (a tag registered again by another family is
    refused) and rebuild the schema's ``road:`` union with it; returns ``family``."""
    known = FAMILIES.get(family.tag)
    if known is not None and known != family:
        raise ScenarioError(f"scenario family {family.tag!r} is registered already "
                            f"(by {known.build.__module__})")  # fmt: skip
    FAMILIES[family.tag] = family
    _rebuild_schema()
    return family


def unregister_family(tag: str) -> None:
    """Remove the family ``tag`` (a plugin's, or a test's) and rebuild the schema."""
    FAMILIES.pop(tag, None)
    _rebuild_schema()


def _rebuild_schema() -> None:
    """Make :class:`ScenarioConfig`'s ``road:`` the registered configs, told apart by
    ``type``."""
    configs = tuple(f.config for f in FAMILIES.values())
    if not configs:
        return
    road = (configs[0] if len(configs) == 1
            else Annotated[typing.Union[configs], Field(discriminator="type")])  # noqa: UP007  # fmt: skip
    ScenarioConfig.model_fields["road"] = FieldInfo.from_annotation(road)
    ScenarioConfig.model_rebuild(force=True)


def family_of(scenario: Scenario) -> Family:
    """The family of a loaded scenario (by its ``road.type``)."""
    return FAMILIES[scenario.config.road.type]


def is_recorded(scenario: Scenario) -> bool:
    """Whether ``scenario`` replays recorded tracks, one of them the ego's."""
    return family_of(scenario).recorded


def family_defaults(tag: Any) -> Mapping[str, Any]:
    """What a file of the family ``tag`` gets where it is silent (nothing for an unknown
    tag: the schema names it)."""
    family = FAMILIES.get(tag) if isinstance(tag, str) else None
    return {} if family is None else family.defaults
