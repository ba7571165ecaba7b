"""Typed settings (pydantic), the trainer's and the evaluation's, validated like the scenario
schema: each field's type, range, choices, default and description are written once, in its
class; the command lines' flags and their help are generated from them
(:func:`neurotrajectory.cli.flags.settings_flag`).

A :class:`Settings` is frozen; a wrong value raises the class's :attr:`Settings.Error` naming
the field, the value and what is expected (every problem of the call at once), never a
pydantic traceback. Numbers are strict: a bool or a string is no number, NumPy scalars are
taken as the Python numbers they hold.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Collection
from typing import Annotated, Any, ClassVar, Union, get_args, get_origin

import annotated_types
import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    ValidationError,
    WrapValidator,
)
from pydantic.fields import FieldInfo
from pydantic_core import PydanticCustomError, core_schema


def _plain(value: Any) -> Any:
    """A NumPy scalar as the Python number it holds (a NumPy bool stays, and is refused)."""
    if isinstance(value, np.integer | np.floating):
        return value.item()
    return value


def _as_given(value: Any, handler) -> Any:
    """A whole number given as a Python ``int`` stays one once checked as a number: the
    settings are saved as given (a run's identity is a digest of them, and runs saved before
    the typed settings kept integers)."""
    checked = handler(value)
    return value if type(value) is int else checked


def _switch(value: Any) -> Any:
    """0 and 1 as False and True (settings saved by hand or by older code); other integers,
    strings and the rest are left to be refused."""
    if type(value) is int and value in (0, 1):
        return bool(value)
    return value


#: An integer (not a bool, a float or a string); NumPy integers accepted.
Integer = Annotated[int, BeforeValidator(_plain), Field(strict=True)]
#: A finite number (not a bool or a string); NumPy numbers accepted (as floats), a Python
#: integer kept as given.
Real = Annotated[float, BeforeValidator(_plain), Field(strict=True, allow_inf_nan=False),
                 WrapValidator(_as_given)]  # fmt: skip
#: A seed: an integer >= 0 (the command lines take up to
#: :data:`gridsim.seeding.MAX_SEED`; the API, as NumPy's generators, any below 2**63).
Seed = Annotated[int, BeforeValidator(_plain), Field(strict=True, ge=0, le=2**63 - 1)]
#: True or False (or 0 and 1; not "yes", "no" or other numbers).
Bool = Annotated[bool, BeforeValidator(_switch), Field(strict=True)]


class OneOf:
    """A field's value must be one of ``options``: a registry read when a value is checked,
    so entries registered later count. ``what`` names the field in errors (default its name).
    """

    def __init__(self, options: Collection[str], what: str | None = None) -> None:
        self.options = options
        self.what = what

    def __get_pydantic_core_schema__(self, source, handler):
        return core_schema.no_info_after_validator_function(self._check, handler(source))

    def _check(self, value):
        if value not in self.options:
            context = {"choices": list(self.options), "what": self.what}
            raise PydanticCustomError("one_of", "not one of {choices}", context)
        return value


class Settings(BaseModel):
    """Frozen, typed settings: unknown keys and wrong values raise :attr:`Error`."""

    model_config = ConfigDict(extra="forbid", frozen=True, validate_default=True)

    #: What a wrong value raises (a subclass sets its package's error).
    Error: ClassVar[type[Exception]] = ValueError

    def __init__(self, **data: Any) -> None:
        try:
            super().__init__(**data)
        except ValidationError as exc:
            raise self.Error(explain(type(self), exc)) from None

    def replace(self, **changes: Any):
        """A copy with ``changes``, validated again."""
        return type(self)(**{**self.as_dict(), **changes})

    def as_dict(self) -> dict[str, Any]:
        """Every field's value (nested settings as dicts; tuples stay tuples)."""
        return self.model_dump()

    @classmethod
    def defaults(cls) -> dict[str, Any]:
        """Every field's default (None where the field has none, or resolves one)."""
        return {name: f.get_default(call_default_factory=True)
                for name, f in cls.model_fields.items()}  # fmt: skip


# -- what a field accepts, for messages and flags ------------------------------------------------


def _metadata(annotation: Any):
    """Every constraint object in ``annotation``, through ``Annotated`` and unions."""
    if get_origin(annotation) is Annotated:
        base, *extra = get_args(annotation)
        for item in extra:
            yield from item.metadata if isinstance(item, FieldInfo) else (item,)
        yield from _metadata(base)
    elif get_origin(annotation) in (Union, type(int | None)):
        for arg in get_args(annotation):
            yield from _metadata(arg)


def _constraints(field: FieldInfo) -> list:
    return [*field.metadata, *_metadata(field.annotation)]


def bounds(field: FieldInfo) -> dict[str, float]:
    """The field's numeric bounds: some of ``gt``, ``ge``, ``lt``, ``le``."""
    out = {}
    for item in _constraints(field):
        for key in ("gt", "ge", "lt", "le"):
            if isinstance(item, annotated_types.BaseMetadata) and hasattr(item, key):
                out[key] = getattr(item, key)
    return out


def choices(field: FieldInfo) -> list[str] | None:
    """The values a :class:`OneOf` field takes now, or None."""
    for item in _constraints(field):
        if isinstance(item, OneOf):
            return list(item.options)
    return None


def base_type(field: FieldInfo) -> type | None:
    """``int``, ``float``, ``bool`` or ``str`` under the field's ``Annotated`` and ``| None``;
    None for anything else (a tuple, a dict, nested settings)."""
    annotation = field.annotation
    while True:
        if get_origin(annotation) is Annotated:
            annotation = get_args(annotation)[0]
            continue
        if get_origin(annotation) in (Union, type(int | None)):
            args = [a for a in get_args(annotation) if a is not type(None)]
            if len(args) == 1:
                annotation = args[0]
                continue
        break
    return annotation if annotation in (int, float, bool, str) else None


def describe_range(b: dict[str, float]) -> str:
    """``>= 2``, ``in (0, 10]``, ...; empty without bounds."""
    low = ("(", b["gt"]) if "gt" in b else ("[", b["ge"]) if "ge" in b else None
    high = (")", b["lt"]) if "lt" in b else ("]", b["le"]) if "le" in b else None
    if low and high:
        return f"in {low[0]}{_number(low[1])}, {_number(high[1])}{high[0]}"
    if low:
        return f"{'>' if low[0] == '(' else '>='} {_number(low[1])}"
    if high:
        return f"{'<' if high[0] == ')' else '<='} {_number(high[1])}"
    return ""


def describe_number(kind: type, limits: dict[str, float]) -> str:
    """What a number field takes, in words: ``an integer >= 2``, ``a finite number in (0,
    10]`` (``kind``: int or float; ``limits``: :func:`bounds`)."""
    rng = describe_range(limits)
    what = "an integer" if kind is int else "a finite number"
    return f"{what} {rng}" if rng else what


def _number(bound: float) -> str:
    return str(bound) if isinstance(bound, int) else f"{bound:g}"


_NUMBER_ERRORS = {"int_type", "int_parsing", "int_from_float", "float_type", "float_parsing",
                  "finite_number", "greater_than", "greater_than_equal", "less_than",
                  "less_than_equal"}  # fmt: skip


def explain(cls: type[Settings], exc: ValidationError) -> str:
    """Every problem of ``exc`` in a line naming the field, the value and what is expected
    (several: joined with ``; ``)."""
    lines = [_problem(cls, e) for e in exc.errors(include_url=False)]
    return lines[0] if len(lines) == 1 else f"{len(lines)} problems: " + "; ".join(lines)


def _problem(cls: type[Settings], e: dict) -> str:
    loc = [str(p) for p in e["loc"]]
    name = ".".join(loc)
    kind, got = e["type"], e.get("input")
    field = cls.model_fields.get(loc[0]) if loc else None
    inner = field.annotation if field is not None else None
    if isinstance(inner, type) and issubclass(inner, Settings):  # nested settings
        if len(loc) > 1:
            return f"{loc[0]}." + _problem(inner, {**e, "loc": e["loc"][1:]})
        if kind == "value_error":  # raised by the nested class's own __init__: its problems
            said = re.sub(r"^\d+ problems: ", "", e["msg"].removeprefix("Value error, "))
            return "; ".join(f"{loc[0]}.{line}" for line in said.split("; "))
    if kind == "extra_forbidden":
        close = difflib.get_close_matches(name, list(cls.model_fields), n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        return f"unknown setting {name!r} of {cls.__name__}{hint}"
    if kind == "missing":
        return f"{name} is required"
    if kind == "one_of":
        return f"unknown {e['ctx']['what'] or name} {got!r}; choose from {e['ctx']['choices']}"
    if kind == "value_error":  # a check in the class's own words
        return e["msg"].removeprefix("Value error, ")
    if kind in _NUMBER_ERRORS and field is not None and len(loc) == 1:
        return f"{name} must be {describe_number(base_type(field), bounds(field))}, got {got!r}"
    if kind in ("bool_type", "bool_parsing"):
        return f"{name} must be true or false, got {got!r}"
    return f"{name}: {e['msg'][:1].lower()}{e['msg'][1:]}, got {got!r}"
